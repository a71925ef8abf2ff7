// Function multiversioning for the CPU pair loops: one binary, the widest vectors the CPU has.
// BGK_CPU_CLONES on the function that holds the loops (GCC compiles it for x86-64-v4 (AVX-512),
// x86-64-v3 (AVX2 and FMA) and baseline x86-64 and picks one at load time); BGK_INLINE_INTO_CLONES
// on its helpers, so that each clone gets its own copy of them compiled for its target. Each clone
// evaluates the same float expressions (no implicit FMA contraction: the library builds with
// -ffp-contract=off; bgk_math.h's explicit BGK_FMA rounds once on every clone), so results do not
// depend on the clone. Shared by the CPU back end and the pair-evaluation roofline
// benchmark (bench/roofline_kernel.cpp), which must be compiled the same way.
#pragma once

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define BGK_CPU_CLONES __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#define BGK_INLINE_INTO_CLONES [[gnu::always_inline]] inline
// Functions written with AVX-512 intrinsics, compiled for the x86-64-v4 clone's instruction set
// and called only where the CPU has it (a clone cannot hold intrinsics its siblings lack).
#define BGK_AVX512_BEAMS 1
#define BGK_TARGET_AVX512 __attribute__((target("arch=x86-64-v4")))
#include <immintrin.h>
#else
#define BGK_CPU_CLONES
#define BGK_INLINE_INTO_CLONES inline
#define BGK_AVX512_BEAMS 0
#endif
