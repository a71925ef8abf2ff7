#!/usr/bin/env python3
"""Seed corpora for the fuzz targets (fuzz/), made with the project's own tools.

usage: fuzz_seeds.py BGKMAP_BINARY OUT_DIR

`bgkmap simulate` makes a one-scan scene (scene.yaml, truth.bt, a binary PCD); a few of its points
are rewritten here in the three PCD encodings and as an OctoMap scan graph (formats bgkmap only
reads; also CARMEN, OctoMap text log, XYZ, PLY, KITTI files and a ROS bag), and `bgkmap build` turns them into .bgk / .ot / .bt maps;
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


def bag_record(fields, data=b""):
    """A ROS bag 2.0 record: its header's name=value fields (each length-prefixed), then its data."""
    header = b"".join(struct.pack("<I", len(k) + 1 + len(v)) + k.encode() + b"=" + v for k, v in fields)
    return struct.pack("<I", len(header)) + header + struct.pack("<I", len(data)) + data


def ros_string(text):
    return struct.pack("<I", len(text)) + text.encode()


def ros_header(stamp, frame):
    return struct.pack("<III", 0, stamp, 0) + ros_string(frame)


def write_rosbag(path, viewpoint, points):
    """A plain (uncompressed) ROS 1 bag: /tf_static placing frame "velodyne" at the sensor in "map",
    the returns as a sensor_msgs/PointCloud2 on /points (t = 1 s) and as a LaserScan on /scan (t = 2 s)."""
    import math
    tx, ty, tz = viewpoint[:3]
    u32, u64 = (lambda v: struct.pack("<I", v)), (lambda v: struct.pack("<Q", v))
    tf = (struct.pack("<I", 1) + ros_header(1, "map") + ros_string("velodyne") +
          struct.pack("<7d", tx, ty, tz, 0, 0, 0, 1))
    xyz = b"".join(struct.pack("<3f", p[0] - tx, p[1] - ty, p[2] - tz) for p in points)
    fields = struct.pack("<I", 3) + b"".join(ros_string(a) + struct.pack("<IBI", 4 * i, 7, 1) for i, a in enumerate("xyz"))
    cloud = (ros_header(1, "velodyne") + struct.pack("<II", 1, len(points)) + fields +
             struct.pack("<BII", 0, 12, 12 * len(points)) + u32(len(xyz)) + xyz + b"\1")
    ranges = [math.hypot(p[0] - tx, p[1] - ty) for p in points]
    laser = (ros_header(2, "velodyne") + struct.pack("<7f", -1.5, 1.5, 3.0 / len(ranges), 0, 0.1, 0.01, 30) +
             u32(len(ranges)) + struct.pack(f"<{len(ranges)}f", *ranges) + u32(0))
    # topic, type, md5sum (rosbag_storage refuses a message whose md5sum is not its type's), message
    connections = [("/tf_static", "tf2_msgs/TFMessage", "94810edda583a504dfda3829e70d7eec", 1, tf),
                   ("/points", "sensor_msgs/PointCloud2", "1158d486dd51d683ce2f1be655c3c181", 1, cloud),
                   ("/scan", "sensor_msgs/LaserScan", "90c7ef2dc6895d81024acba2ac42f369", 2, laser)]
    def connection(conn, topic, type_, md5):
        info = b"".join(struct.pack("<I", len(k) + 1 + len(v)) + k.encode() + b"=" + v.encode()
                        for k, v in (("topic", topic), ("type", type_), ("md5sum", md5), ("message_definition", "")))
        return bag_record([("op", b"\7"), ("conn", u32(conn)), ("topic", topic.encode())], info)
    chunk, offsets = b"", []
    for conn, (topic, type_, md5, sec, message) in enumerate(connections):
        chunk += connection(conn, topic, type_, md5)
        offsets.append(len(chunk))
        chunk += bag_record([("op", b"\2"), ("conn", u32(conn)), ("time", struct.pack("<II", sec, 0))], message)
    version = b"#ROSBAG V2.0\n"
    header_fields = lambda index_pos: [("op", b"\3"), ("index_pos", u64(index_pos)), ("conn_count", u32(3)),
                                       ("chunk_count", u32(1))]
    chunk_pos = len(version) + len(bag_record(header_fields(0)))
    body = bag_record([("op", b"\5"), ("compression", b"none"), ("size", u32(len(chunk)))], chunk)
    for conn, (_, _, _, sec, _) in enumerate(connections):
        body += bag_record([("op", b"\4"), ("ver", u32(1)), ("conn", u32(conn)), ("count", u32(1))],
                           struct.pack("<III", sec, 0, offsets[conn]))
    index_pos = chunk_pos + len(body)
    index = b"".join(connection(conn, c[0], c[1], c[2]) for conn, c in enumerate(connections))
    index += bag_record([("op", b"\6"), ("ver", u32(1)), ("chunk_pos", u64(chunk_pos)), ("start_time", struct.pack("<II", 1, 0)),
                         ("end_time", struct.pack("<II", 2, 0)), ("count", u32(3))],
                        b"".join(struct.pack("<II", conn, 1) for conn in range(3)))
    bag = version + bag_record(header_fields(index_pos)) + body + index
    # fuzz_rosbag: the first byte picks the poses, /tf in "map" (0) or a list of poses (1).
    for name, first in (("tf", b"\0"), ("poses", b"\1")):
        with open(os.path.join(path, name), "wb") as f:
            f.write(first + bag)


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    bgkmap, out = os.path.abspath(sys.argv[1]), sys.argv[2]
    for d in ("pcd", "graph", "bgk", "ot", "bt", "scene", "carmen", "octomap_log", "xyz", "ply", "kitti", "rosbag"):
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
        write_rosbag(os.path.join(out, "rosbag"), viewpoint, points)
        scan = os.path.join(out, "pcd", "binary.pcd")
        for name, flags in (("depth2", ["--block-depth", "2", "--resolution", "0.5"]),
                            ("depth3", ["--block-depth", "3", "--resolution", "1"])):
            subprocess.run([bgkmap, "build", scan, "-q", "--backend", "cpu", "--threads", "1", *flags,
                            "-o", os.path.join(out, "bgk", name + ".bgk"), "-o", os.path.join(out, "ot", name + ".ot"),
                            "-o", os.path.join(out, "bt", name + ".bt")], check=True)


if __name__ == "__main__":
    main()
