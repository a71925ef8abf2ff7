"""Small scan files of every format bgkmap reads, written by hand from their specifications.

`room_scans()` gives the scans of a sensor in a closed box room (analytic ray casts), so a map of
any of them has walls where the room has them.
"""
import math
import struct

ROOM = ((-4.97, 4.97), (-3.97, 3.97), (-0.03, 2.97))  # x, y, z bounds of the box room (m), off cell faces


def wall_hit(origin, direction):
    """Where a ray from inside ROOM leaves it."""
    t = min(((hi if d > 0 else lo) - o) / d for o, d, (lo, hi) in zip(origin, direction, ROOM) if d != 0)
    return tuple(o + t * d for o, d in zip(origin, direction))


def room_scans(origins=((-1.0, 0.0, 1.0), (0.0, 0.0, 1.0), (1.0, 0.0, 1.0)), elevations_deg=range(-20, 21, 5)):
    """[(origin, world points)]: a beam every degree of azimuth at each elevation."""
    scans = []
    for origin in origins:
        points = []
        for el in elevations_deg:
            for az in range(360):
                a, e = math.radians(az), math.radians(el)
                points.append(wall_hit(origin, (math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e))))
        scans.append((origin, points))
    return scans


def in_sensor_frame(origin, points):
    """The points relative to an unturned sensor at origin."""
    return [tuple(p - o for p, o in zip(point, origin)) for point in points]


def write_scan_graph(path, nodes):
    """An OctoMap binary scan graph (ScanGraph::writeBinary's layout) of nodes [(origin, points)]."""
    def vector(values):
        return struct.pack("<i", len(values)) + struct.pack(f"<{len(values)}d", *values)

    data = struct.pack("<I", len(nodes))
    for i, (origin, points) in enumerate(nodes):
        data += struct.pack("<I", len(points)) + b"".join(vector(p) for p in points)
        data += vector(origin) + vector((1.0, 0.0, 0.0, 0.0)) + struct.pack("<I", i)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(data + struct.pack("<I", 0))


def write_octomap_log(path, scans):
    """An OctoMap text scan log: `NODE x y z roll pitch yaw`, then the node's sensor-frame points."""
    lines = []
    for origin, points in scans:
        lines.append("NODE %g %g %g 0 0 0" % origin)
        lines += ["%.6f %.6f %.6f" % p for p in in_sensor_frame(origin, points)]
    path.write_text("\n".join(lines) + "\n")


def write_carmen_log(path, origins, beams=180):
    """A CARMEN log of FLASER lines: beam i at -90 deg + i * 180 / n from the laser's heading 0."""
    lines = ["# CARMEN laser log", "ODOM 0 0 0 0 0 0 0 host 0"]
    for k, (x, y, _) in enumerate(origins):
        ranges = []
        for i in range(beams):
            a = math.radians(-90 + i * 180 / beams)
            hit = wall_hit((x, y, 1.0), (math.cos(a), math.sin(a), 0.0))
            ranges.append("%.3f" % math.hypot(hit[0] - x, hit[1] - y))
        lines.append(f"FLASER {beams} {' '.join(ranges)} {x} {y} 0 {x} {y} 0 {k}.0 host {k}.0")
    path.write_text("\n".join(lines) + "\n")


def write_ply(path, points):
    """An ascii PLY of vertices x y z."""
    header = ["ply", "format ascii 1.0", f"element vertex {len(points)}",
              "property float x", "property float y", "property float z", "end_header"]
    path.write_text("\n".join(header + ["%.6f %.6f %.6f" % p for p in points]) + "\n")


def write_tum_poses(path, origins):
    """TUM pose lines `time x y z qx qy qz qw`, unturned."""
    path.write_text("".join(f"{i}.0 {x} {y} {z} 0 0 0 1\n" for i, (x, y, z) in enumerate(origins)))


def write_kitti_sequence(folder, scans):
    """A KITTI odometry sequence folder: velodyne/NNNNNN.bin (float32 x y z reflectance, sensor
    frame), poses.txt (3x4 rows, camera 0 of each scan in camera 0 of the first), calib.txt (Tr)."""
    (folder / "velodyne").mkdir(parents=True)
    first = scans[0][0]
    poses = []
    for i, (origin, points) in enumerate(scans):
        local = in_sensor_frame(origin, points)
        (folder / "velodyne" / f"{i:06d}.bin").write_bytes(b"".join(struct.pack("<4f", *p, 0.5) for p in local))
        dx, dy, dz = (o - f for o, f in zip(origin, first))
        poses.append(f"1 0 0 {dx} 0 1 0 {dy} 0 0 1 {dz}\n")
    (folder / "poses.txt").write_text("".join(poses))
    identity = "1 0 0 0 0 1 0 0 0 0 1 0"
    (folder / "calib.txt").write_text(f"P0: {identity}\nTr: {identity}\n")


def write_pcd(path, origin, points):
    """An ascii PCD of world-frame points, the sensor pose in VIEWPOINT (unturned)."""
    header = ["# .PCD v0.7", "VERSION 0.7", "FIELDS x y z", "SIZE 4 4 4", "TYPE F F F", "COUNT 1 1 1",
              f"WIDTH {len(points)}", "HEIGHT 1", "VIEWPOINT %g %g %g 1 0 0 0" % origin,
              f"POINTS {len(points)}", "DATA ascii"]
    path.write_text("\n".join(header + ["%.6f %.6f %.6f" % p for p in points]) + "\n")
