#!/usr/bin/env python3
"""Derives the polynomial bgk_sparse_kernel_of_ratio (include/bgkmap/core/bgk_math.h) evaluates.

The sparse kernel, with r = d / l and u = 1 - r, is k / sigma0 = u^5 g(u^2), where
    g(v) = sum_{n>=2} (-1)^n (2 pi)^(2n) v^(n-2) (2n - 2) / (3 (2n + 1)!)
is entire. g is interpolated at the Chebyshev-Lobatto nodes of t = 2v - 1 in [-1, 1] (which
include v = 1, so k(0) = sigma0 holds exactly), converted to monomials in t, rounded to float, and
the float evaluation the header performs (same operations, same order, every step rounded to
float) is compared with the closed form in double over the support.

Usage: scripts/fit_sparse_kernel.py [DEGREE]   (default 7, the header's)
Prints the coefficients (c0 first) and the worst relative error where k > 1e-9 sigma0.
Pure Python (no numpy).
"""
import math
import struct
import sys

TWO_PI = 2 * math.pi


def f32(x):
    return struct.unpack("f", struct.pack("f", x))[0]


def kernel_closed_form(r):
    if r >= 1:
        return 0.0
    x = TWO_PI * r
    return (2 + math.cos(x)) / 3 * (1 - r) + math.sin(x) / TWO_PI


def g(v):
    # Converges for every v in [0, 1]; the cancellation (terms up to ~16) costs ~1e-15 in double.
    return sum((-1) ** m * TWO_PI ** (2 * m + 4) * (2 * m + 2) / (3 * math.factorial(2 * m + 5)) * v ** m
               for m in range(40))


def reference(r):
    # The closed form cancels near r = 1 even in double; the series form is exact there.
    u = 1 - r
    return kernel_closed_form(r) if r < 0.6 else u ** 5 * g(u * u)


def chebyshev_lobatto_monomials(degree):
    nodes = [math.cos(math.pi * j / degree) for j in range(degree + 1)]
    values = [g((t + 1) / 2) for t in nodes]
    cheb = []
    for k in range(degree + 1):
        s = sum((0.5 if j in (0, degree) else 1.0) * values[j] * math.cos(math.pi * k * j / degree)
                for j in range(degree + 1))
        cheb.append(s * 2.0 / degree * (0.5 if k in (0, degree) else 1.0))
    basis = [[1.0], [0.0, 1.0]]  # T_k as monomials in t
    for k in range(2, degree + 1):
        cur = [0.0] * (k + 1)
        for i, c in enumerate(basis[k - 1]):
            cur[i + 1] += 2 * c
        for i, c in enumerate(basis[k - 2]):
            cur[i] -= c
        basis.append(cur)
    mono = [0.0] * (degree + 1)
    for k in range(degree + 1):
        for i, c in enumerate(basis[k]):
            mono[i] += cheb[k] * c
    return [f32(c) for c in mono]


def evaluate_as_the_header(coefficients, r):
    r = f32(r)
    u = f32(1.0 - r)
    v = f32(u * u)
    t = f32(f32(2.0 * v) - 1.0)
    p = coefficients[-1]
    for c in reversed(coefficients[:-1]):
        p = f32(f32(p * t) + c)
    return f32(f32(f32(v * v) * u) * p) if r < 1 else 0.0


def main():
    degree = int(sys.argv[1]) if len(sys.argv) > 1 else 7
    coefficients = chebyshev_lobatto_monomials(degree)
    worst = 0.0
    for i in range(100001):
        r = f32(i / 100000)
        expected = reference(r)
        got = evaluate_as_the_header(coefficients, r)
        if expected > 1e-9:
            worst = max(worst, abs(got - expected) / expected)
    print("coefficients (c0 .. c%d):" % degree)
    for c in coefficients:
        print("  %.9g" % c)
    print("k(0) / sigma0 = %r, k(l) = %r" % (evaluate_as_the_header(coefficients, 0.0),
                                              evaluate_as_the_header(coefficients, 1.0)))
    print("worst relative error where k > 1e-9 sigma0: %.2e" % worst)


if __name__ == "__main__":
    main()
