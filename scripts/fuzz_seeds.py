#!/usr/bin/env python3
"""Seed corpora for the fuzz targets (fuzz/), made with the project's own tools.

usage: fuzz_seeds.py BGKMAP_BINARY OUT_DIR

`bgkmap simulate` makes a one-scan scene (scene.yaml, truth.bt, a binary PCD); a few of its points
are rewritten here in the three PCD encodings and as an OctoMap scan graph (formats bgkmap only
reads; also CARMEN, OctoMap text log, XYZ, PLY and KITTI files), and `bgkmap build` turns them into .bgk / .ot / .bt maps;
the build config seeds are fuzz/seeds/config's, copied. Small on purpose: the fuzzers
run with -max_len of a few KiB.
"""
import os
import shutil
import struct
import subprocess
import sys
import tempfile


def read_binary_pcd(path):
    data = open(path, "rb").read()
    end = data.index(b"DATA binary\n") + len(b"DATA binary\n")
    header = data[:end].decode()
    viewpoint = next(l for l in header.splitlines() if l.startswith("VIEWPOINT")).split()[1:]
    n = int(next(l for l in header.splitlines() if l.startswith("POINTS")).split()[1])
    points = [struct.unpack_from("<3f", data, end + 12 * i) for i in range(n)]
    return [float(v) for v in viewpoint], points


def pcd_header(viewpoint, n, encoding, extra_field=False):
    fields = "x y z intensity" if extra_field else "x y z"
    k = 4 if extra_field else 3
    return ("# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n"
            f"FIELDS {fields}\nSIZE {' '.join(['4'] * k)}\nTYPE {' '.join(['F'] * k)}\n"
            f"COUNT {' '.join(['1'] * k)}\nWIDTH {n}\nHEIGHT 1\n"
            f"VIEWPOINT {' '.join(repr(v) for v in viewpoint)}\nPOINTS {n}\nDATA {encoding}\n").encode()


def lzf_literals(raw):
    """An LZF stream of literal runs only (at most 32 bytes each): valid input to PCL's decoder."""
    out = bytearray()
    for i in range(0, len(raw), 32):
        chunk = raw[i:i + 32]
        out.append(len(chunk) - 1)
        out += chunk
    return bytes(out)


def write_pcds(out, viewpoint, points):
    n = len(points)
    with open(os.path.join(out, "pcd", "binary.pcd"), "wb") as f:
        f.write(pcd_header(viewpoint, n, "binary"))
        for p in points:
            f.write(struct.pack("<3f", *p))
    with open(os.path.join(out, "pcd", "ascii.pcd"), "wb") as f:
        f.write(pcd_header(viewpoint, n, "ascii", extra_field=True))
        for i, p in enumerate(points):
            f.write((" ".join(repr(v) for v in p) + f" {i}\n").encode())
    # binary_compressed stores each field's values together (x of every point, then y, ...).
    raw = b"".join(struct.pack(f"<{n}f", *[p[a] for p in points]) for a in range(3))
    packed = lzf_literals(raw)
    with open(os.path.join(out, "pcd", "binary_compressed.pcd"), "wb") as f:
        f.write(pcd_header(viewpoint, n, "binary_compressed"))
        f.write(struct.pack("<II", len(packed), len(raw)) + packed)


def write_graph(path, viewpoint, points):
    """liboctomap's ScanGraph::writeBinary layout (src/io/scan_graph_io.cpp): two nodes, one edge."""
    def pose(t, q):
        return struct.pack("<i3d", 3, *t) + struct.pack("<i4d", 4, *q)
    tx, ty, tz = viewpoint[:3]
    with open(path, "wb") as f:
        f.write(struct.pack("<I", 2))
        for node_id, shift in ((0, 0.0), (1, 0.5)):
            f.write(struct.pack("<I", len(points)))
            for p in points:  # sensor frame: relative to the node's position
                f.write(struct.pack("<i3d", 3, p[0] - tx, p[1] - ty, p[2] - tz))
            f.write(pose((tx + shift, ty, tz), (1.0, 0.0, 0.0, 0.0)))
            f.write(struct.pack("<I", node_id))
        f.write(struct.pack("<I", 1))
        f.write(struct.pack("<II", 0, 1) + pose((0.5, 0, 0), (1.0, 0, 0, 0)) + struct.pack("<d", 1.0))


def write_text_logs(out, viewpoint, points):
    """The same returns as CARMEN, OctoMap text log, XYZ, PLY, a TUM pose list and a KITTI folder's files."""
    import math
    tx, ty, tz = viewpoint[:3]
    ranges = [math.hypot(p[0] - tx, p[1] - ty) for p in points]
    r = " ".join(f"{v:.3f}" for v in ranges)
    n = len(ranges)
    with open(os.path.join(out, "carmen", "scans.log"), "w") as f:
        f.write("# message formats defined: PARAM ODOM FLASER ROBOTLASER1\nPARAM robot_frontlaser_offset 0.0 nohost 0\n")
        f.write(f"ODOM {tx} {ty} 0 0 0 0 0.1 nohost 0.1\n")
        f.write(f"FLASER {n} {r} {tx} {ty} 0.5 {tx} {ty} 0.5 0.2 nohost 0.2\n")
        f.write(f"ROBOTLASER1 0 -1.5708 3.1416 {3.1416 / n:.5f} 81.9 0.01 0 {n} {r} 0 "
                f"{tx} {ty} 0.5 {tx} {ty} 0.5 0 0 0.55 0.375 1000000 0.3 nohost 0.3\n")
    with open(os.path.join(out, "octomap_log", "scans.dat"), "w") as f:
        for k, (x, yaw) in enumerate(((tx, 0.0), (tx + 0.5, 0.3))):
            f.write(f"# node {k}\nNODE {x} {ty} {tz} 0 0.1 {yaw}\n")
            for p in points:
                f.write(f"{p[0] - tx} {p[1] - ty} {p[2] - tz}\n")
    with open(os.path.join(out, "xyz", "scan.xyz"), "w") as f:
        f.write("# x y z intensity\n" + "".join(f"{p[0]} {p[1]} {p[2]} 7\n" for p in points))
    with open(os.path.join(out, "xyz", "poses.txt"), "w") as f:
        f.write("# time x y z qx qy qz qw\n0 1.5 3.3 1 0 0 0 1\n0.1 2 3.3 1 0 0 0.0998 0.995\n")
    head = f"ply\nformat {{}} 1.0\ncomment bgkmap seed\nelement vertex {n}\n" \
           "property float x\nproperty float y\nproperty float z\nproperty uchar intensity\n" \
           "element face 0\nproperty list uchar int vertex_indices\nend_header\n"
    with open(os.path.join(out, "ply", "ascii.ply"), "w") as f:
        f.write(head.format("ascii") + "".join(f"{p[0]} {p[1]} {p[2]} 7\n" for p in points))
    for order, fmt in (("binary_little_endian", "<"), ("binary_big_endian", ">")):
        with open(os.path.join(out, "ply", order + ".ply"), "wb") as f:
            f.write(head.format(order).encode() + b"".join(struct.pack(fmt + "3fB", *p, 7) for p in points))
    # fuzz_kitti: the first byte picks calib.txt (0), poses.txt (1) or velodyne/000001.bin (2).
    kitti = os.path.join(out, "kitti")
    with open(os.path.join(kitti, "calib"), "wb") as f:
        f.write(b"\0P0: 1 0 0 0 0 1 0 0 0 0 1 0\nTr: 0 -1 0 0 0 0 -1 0 1 0 0 0\n")
    with open(os.path.join(kitti, "poses"), "wb") as f:
        f.write(b"\1" + b"1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0.5 0 1 0 0 0 0 1 1\n")
    with open(os.path.join(kitti, "velodyne"), "wb") as f:
        f.write(b"\2" + b"".join(struct.pack("<4f", p[0] - tx, p[1] - ty, p[2] - tz, 0.5) for p in points))


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    bgkmap, out = os.path.abspath(sys.argv[1]), sys.argv[2]
    for d in ("pcd", "graph", "bgk", "ot", "bt", "scene", "carmen", "octomap_log", "xyz", "ply", "kitti"):
        os.makedirs(os.path.join(out, d), exist_ok=True)
    # Config files are written by hand (fuzz/seeds/config): every kind of key, no tool makes them.
    shutil.copytree(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "fuzz", "seeds", "config"),
                    os.path.join(out, "config"))
    with tempfile.TemporaryDirectory() as tmp:
        sim = os.path.join(tmp, "sim")
        subprocess.run([bgkmap, "simulate", "structured", "-o", sim, "--scans", "1", "--sensor", "planar",
                        "--truth-resolution", "1", "-q"], check=True)
        shutil.copy(os.path.join(sim, "scene.yaml"), os.path.join(out, "scene", "structured.yaml"))
        shutil.copy(os.path.join(sim, "truth.bt"), os.path.join(out, "bt", "truth.bt"))
        viewpoint, points = read_binary_pcd(os.path.join(sim, "scans", "scan_00000.pcd"))
        points = points[::90]  # a dozen returns
        write_pcds(out, viewpoint, points)
        write_graph(os.path.join(out, "graph", "two_nodes.graph"), viewpoint, points)
        write_text_logs(out, viewpoint, points)
        scan = os.path.join(out, "pcd", "binary.pcd")
        for name, flags in (("depth2", ["--block-depth", "2", "--resolution", "0.5"]),
                            ("depth3", ["--block-depth", "3", "--resolution", "1"])):
            subprocess.run([bgkmap, "build", scan, "-q", "--backend", "cpu", "--threads", "1", *flags,
                            "-o", os.path.join(out, "bgk", name + ".bgk"), "-o", os.path.join(out, "ot", name + ".ot"),
                            "-o", os.path.join(out, "bt", name + ".bt")], check=True)


if __name__ == "__main__":
    main()
