#!/usr/bin/env python3
"""The recipes of the datasets bgkmap reads (datasets/recipes/NAME.toml; the table: datasets/README.md).

Usage: datasets/recipe.py list
       datasets/recipe.py show NAME
       datasets/recipe.py check NAME... | --all [--bgkmap build/bgkmap] [--work DIR]   (--all: not campus)
       datasets/recipe.py prepare NAME --from DOWNLOAD

check: the files a recipe expects, in the datasets folder (datasets/locate.py: $BGKMAP_DATASETS, else
../shared/datasets beside the checkout): their SHA-256 where the recipe knows it, else their structure
(scan graph records, PCD headers, a KITTI sequence's scans against its poses); with --bgkmap also
the scans and points `bgkmap build --method counting` reads (on 1 m cells with the recipe's
--max-range: the cheapest build that reads everything; a generated dataset is simulated into
--work, a temporary folder by default, and counted from the PCD headers it wrote). Prints what it
checked and the command that maps the dataset; a dataset that is missing or does not match is one
line on stderr naming the file, and the exit status is 1.
prepare: puts a download where check expects it, in $BGKMAP_DATASETS (which it must name: the shared
default is read-only): a scan graph copied, gunzipped if .gz; PCD files copied; a KITTI odometry
download's sequences linked with their poses; then checks it.
"""
import argparse
import gzip
import hashlib
import json
import os
import pathlib
import shlex
import shutil
import struct
import subprocess
import sys
import tempfile
import tomllib

import locate

RECIPES = pathlib.Path(__file__).resolve().parent / "recipes"


class Failed(Exception):
    """A check that did not pass; str() is its one-line message."""


def load(name):
    path = RECIPES / f"{name}.toml"
    if not path.is_file():
        known = ", ".join(sorted(p.stem for p in RECIPES.glob("*.toml")))
        raise Failed(f"recipe: no recipe '{name}' (known: {known})")
    with open(path, "rb") as f:
        recipe = tomllib.load(f)
    recipe["name"] = name
    return recipe


def all_names():
    return sorted(p.stem for p in RECIPES.glob("*.toml"))


def count(n):
    return f"{n:,}"


def sha256(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


# --- structure checks: exact counts read from the files' own records ------------------------------

def scan_graph_points(path):
    """The point count of each node of an OctoMap binary scan graph (liboctomap's ScanGraph::writeBinary,
    little-endian: uint32 nodes; per node uint32 n, n x (int32 3, 3 float64), a pose (int32 3, 3 float64,
    int32 4, 4 float64), uint32 id; then uint32 edges of 84 bytes each), checked to end the file."""
    point_bytes, pose_bytes = 4 + 24, 28 + 36
    size = path.stat().st_size
    points = []
    with open(path, "rb") as f:
        def read(n, what):
            data = f.read(n)
            if len(data) != n:
                raise Failed(f"recipe: {path}: ends inside {what}: not an OctoMap scan graph, or truncated")
            return data

        nodes = struct.unpack("<I", read(4, "the node count"))[0]
        for k in range(nodes):
            n = struct.unpack("<I", read(4, f"node {k}'s point count"))[0]
            if f.tell() + n * point_bytes + pose_bytes + 4 > size:
                raise Failed(f"recipe: {path}: node {k} claims {count(n)} points, more than the file holds")
            if n and struct.unpack("<i", read(4, f"node {k}'s first point"))[0] != 3:
                raise Failed(f"recipe: {path}: node {k}'s points are not 3-vectors: not an OctoMap scan graph")
            f.seek(f.tell() - (4 if n else 0) + n * point_bytes)
            pose = read(pose_bytes, f"node {k}'s pose")
            if struct.unpack_from("<i", pose, 0)[0] != 3 or struct.unpack_from("<i", pose, 28)[0] != 4:
                raise Failed(f"recipe: {path}: node {k}'s pose is not a pose record: not an OctoMap scan graph")
            read(4, f"node {k}'s id")
            points.append(n)
        edges = struct.unpack("<I", read(4, "the edge count"))[0]
        if f.tell() + edges * 84 != size:
            raise Failed(f"recipe: {path}: {count(size - f.tell())} bytes after the nodes, not {count(edges)} edges of 84")
    return points


def pcd_header(path):
    """A PCD file's header fields (upper-case keys), checked against the file's size for binary data."""
    fields = {}
    with open(path, "rb") as f:
        for _ in range(64):
            line = f.readline().decode("ascii", "replace").strip()
            if not line or line.startswith("#"):
                continue
            key, _, value = line.partition(" ")
            fields[key.upper()] = value.split()
            if key.upper() == "DATA":
                break
        header_end = f.tell()
    for key in ("FIELDS", "SIZE", "COUNT", "POINTS", "DATA"):
        if key not in fields:
            raise Failed(f"recipe: {path}: no {key} line in the first 64 lines: not a PCD file")
    points = int(fields["POINTS"][0])
    if fields["DATA"][0] == "binary":
        point_size = sum(int(s) * int(c) for s, c in zip(fields["SIZE"], fields["COUNT"]))
        if header_end + points * point_size > path.stat().st_size:
            raise Failed(f"recipe: {path}: {count(points)} points of {point_size} bytes do not fit in the file (truncated?)")
    return fields


def pcd_folder(folder):
    """Scans and points of a folder of PCD files whose sensor origins are their VIEWPOINTs."""
    files = sorted(folder.glob("*.pcd"))
    if not files:
        raise Failed(f"recipe: {folder}: no .pcd files")
    origins = set()
    points = 0
    for file in files:
        header = pcd_header(file)
        if "VIEWPOINT" not in header:
            raise Failed(f"recipe: {file}: no VIEWPOINT line: the sensor origin is unknown (bgkmap build --poses or --origin gives it)")
        origins.add(tuple(header["VIEWPOINT"][:3]))
        points += int(header["POINTS"][0])
    if len(files) > 1 and len(origins) == 1:
        raise Failed(f"recipe: {folder}: every scan has the VIEWPOINT {' '.join(origins.pop())}: sensor origins not recorded "
                     "(bgkmap build --poses gives them)")
    return len(files), points


def kitti_sequence(folder):
    """Scans and points of a KITTI odometry sequence as bgkmap reads it: velodyne/*.bin (16 bytes a
    point), one poses.txt line (12 numbers) a scan, calib.txt with a Tr: line."""
    for part in ("velodyne", "poses.txt", "calib.txt"):
        if not (folder / part).exists():
            raise Failed(f"recipe: {folder / part} is missing (datasets/recipe.py prepare kitti_odometry --from KITTI_ROOT links it)")
    calib = (folder / "calib.txt").read_text().splitlines()
    if not any(line.startswith("Tr:") and len(line.split()) == 13 for line in calib):
        raise Failed(f"recipe: {folder / 'calib.txt'}: no 'Tr:' line of 12 numbers (velodyne to camera 0)")
    poses = [line for line in (folder / "poses.txt").read_text().splitlines() if line.strip()]
    for i, line in enumerate(poses):
        if len(line.split()) != 12:
            raise Failed(f"recipe: {folder / 'poses.txt'}: line {i + 1} has {len(line.split())} numbers, expected 12 (a 3x4 pose)")
    scans = sorted((folder / "velodyne").glob("*.bin"))
    points = 0
    for scan in scans:
        size = scan.stat().st_size
        if size % 16:
            raise Failed(f"recipe: {scan}: {count(size)} bytes is not a whole number of 16-byte points")
        points += size // 16
    if len(poses) != len(scans):
        raise Failed(f"recipe: {folder / 'poses.txt'}: {len(poses)} poses for {len(scans)} scans in velodyne/ (one pose a scan)")
    return len(scans), points


# --- what bgkmap reads -------------------------------------------------------------------------------

def count_flags(build_flags):
    """The recipe's --max-range (no-return readings must not become far hits) on 1 m cells: the
    cheapest build that reads every scan and point as the recipe's own build does."""
    words = shlex.split(build_flags)
    kept = words[words.index("--max-range"):][:2] if "--max-range" in words else []
    return kept + ["--resolution", "1"]


def bgkmap_counts(bgkmap, inputs, build_flags, work):
    """scans and points_read of `bgkmap build --method counting` on the inputs (its report's counts)."""
    report = work / "count.json"
    command = [bgkmap, "build", *map(str, inputs), *count_flags(build_flags), "--method", "counting", "-q", "--threads", "2",
               "-o", str(work / "count.bgk"), "--report", str(report)]
    r = subprocess.run(command, capture_output=True, text=True)
    if r.returncode != 0:
        last = (r.stderr.strip().splitlines() or ["no message"])[-1]
        raise Failed(f"recipe: bgkmap build of {' '.join(map(str, inputs))} failed: {last}")
    counts = json.loads(report.read_text())["counts"]
    return counts["scans"], counts["points_read"]


def compare(name, what, found, expect, source):
    scans, points = found
    want_scans, want_points = expect.get("scans"), expect.get("points")
    said = f"{count(scans)} scan{'s' * (scans != 1)}, {count(points)} points"
    if want_scans is not None and scans != want_scans:
        raise Failed(f"recipe: {name}: {what} {count(scans)} scans where the recipe expects {count(want_scans)} ({source})")
    if want_points is not None and points != want_points:
        raise Failed(f"recipe: {name}: {what} {count(points)} points where the recipe expects {count(want_points)} ({source})")
    known = "as expected" if want_scans is not None else "no expected count known"
    print(f"{name}: {what} {said} ({known})")


def map_command(recipe, inputs):
    flags = recipe.get("build_flags", "")
    return " ".join(["bgkmap build", *(shlex.quote(str(i)) for i in inputs), "-o", f"{recipe['name']}.bgk", flags]).strip()


STRUCTURES = {  # structure name: (what it reads, the function giving (scans, points))
    "scan_graph": ("the scan graph holds", lambda path: (len(pts := scan_graph_points(path)), sum(pts))),
    "pcd_folder": ("the PCD headers give", pcd_folder),
    "kitti": ("the sequence holds", kitti_sequence),
}


def units(recipe, paths):
    """(label, inputs, expected counts) of each thing the recipe maps: one, or a KITTI root's sequences."""
    if recipe.get("structure") != "kitti":
        return [(recipe["name"], paths, recipe.get("expect", {}))]
    sequences = sorted(p for p in paths[0].iterdir() if p.is_dir())
    if not sequences:
        raise Failed(f"recipe: {recipe['name']}: {paths[0]} holds no sequence folders "
                     f"(datasets/recipe.py prepare {recipe['name']} --from KITTI_ROOT)")
    return [(f"{recipe['name']} {s.name}", [s], {"scans": recipe["expect_sequences"].get(s.name)}) for s in sequences]


def check_files(recipe, folder, bgkmap, work):
    name = recipe["name"]
    paths = [locate.require(rel, f"recipe: {name}", folder) for rel in recipe["inputs"]]
    digests = recipe.get("sha256", {})
    for rel, digest in digests.items():
        path = locate.require(rel, f"recipe: {name}", folder)
        got = sha256(path)
        if got != digest:
            raise Failed(f"recipe: {name}: {path}: SHA-256 {got[:16]}... is not the recipe's {digest[:16]}... "
                         "(another or a damaged copy)")
    if digests:
        print(f"{name}: SHA-256 of {len(digests)} file{'s' * (len(digests) != 1)} as expected")
    source = recipe.get("expect_source", "the recipe")
    structure = STRUCTURES.get(recipe.get("structure"))
    for label, inputs, expect in units(recipe, paths):
        if structure:
            compare(label, structure[0], structure[1](inputs[0]), expect, source)
        if bgkmap:
            compare(label, "bgkmap build reads", bgkmap_counts(bgkmap, inputs, recipe.get("build_flags", ""), work), expect, source)
        elif not structure:
            print(f"{label}: scan counts not measured (give --bgkmap build/bgkmap)")
        print(f"{label}: map it with: {map_command(recipe, inputs)}")


def check_generated(recipe, bgkmap, work):
    name = recipe["name"]
    if not bgkmap:
        raise Failed(f"recipe: {name}: a generated dataset is checked by simulating it: give --bgkmap build/bgkmap")
    out = work / name
    r = subprocess.run([bgkmap, "simulate", recipe["preset"], "-o", str(out), "-q", "--overwrite"],
                       capture_output=True, text=True)
    if r.returncode != 0:
        last = (r.stderr.strip().splitlines() or ["no message"])[-1]
        raise Failed(f"recipe: {name}: bgkmap simulate {recipe['preset']} failed: {last}")
    compare(name, "bgkmap simulate wrote", pcd_folder(out / "scans"), recipe["expect"], recipe.get("expect_source", "the recipe"))
    print(f"{name}: map it with: bgkmap simulate {recipe['preset']} -o DIR && {map_command(recipe, ['DIR/scans'])}")


def check(name, folder, bgkmap, work):
    recipe = load(name)
    if recipe["kind"] == "generated":
        check_generated(recipe, bgkmap, work)
    else:
        check_files(recipe, folder, bgkmap, work)
    print(f"{name}: ok")


# --- prepare a download ------------------------------------------------------------------------------

def copy_atomically(source, target):
    target.parent.mkdir(parents=True, exist_ok=True)
    partial = target.with_name(target.name + ".partial")
    opener = gzip.open if source.suffix == ".gz" else open
    with opener(source, "rb") as src, open(partial, "wb") as dst:
        shutil.copyfileobj(src, dst, 1 << 20)
    os.replace(partial, target)


def prepare(name, source, folder):
    recipe = load(name)
    how = recipe.get("prepare")
    if not how:
        raise Failed(f"recipe: {name}: nothing to prepare ({recipe['kind']} dataset)")
    if not os.environ.get(locate.ENV):
        raise Failed(f"recipe: prepare writes into ${locate.ENV}: set it to a datasets folder of your own "
                     f"(the default {folder} is shared and read-only)")
    source = pathlib.Path(source)
    if not source.exists():
        raise Failed(f"recipe: {name}: {source} not found (the download --from names)")
    target = folder / recipe["inputs"][0]
    if how == "copy_file":
        copy_atomically(source, target)
    elif how == "copy_pcd":
        files = sorted(source.glob("*.pcd"))
        if not files:
            raise Failed(f"recipe: {name}: {source} holds no .pcd files")
        for f in files:
            copy_atomically(f, target / f.name)
    elif how == "link_kitti":
        linked = 0
        for poses in sorted((source / "poses").glob("*.txt")):
            sequence = source / "sequences" / poses.stem
            if not ((sequence / "velodyne").is_dir() and (sequence / "calib.txt").is_file()):
                continue
            out = target / poses.stem
            out.mkdir(parents=True, exist_ok=True)
            for link, to in (("velodyne", sequence / "velodyne"), ("calib.txt", sequence / "calib.txt"), ("poses.txt", poses)):
                if (out / link).is_symlink() or (out / link).exists():
                    (out / link).unlink()
                (out / link).symlink_to(to.resolve())
            linked += 1
        if not linked:
            raise Failed(f"recipe: {name}: {source} has no poses/NN.txt with sequences/NN/velodyne/ and calib.txt "
                         "beside it (a KITTI odometry root)")
    print(f"{name}: prepared {target}")


def show(name):
    recipe = load(name)
    for key in ("title", "kind", "source", "licence", "size", "format", "get", "paper_settings", "notes"):
        if key in recipe:
            print(f"{key}: {recipe[key]}")
    if recipe["kind"] == "generated":
        print(f"map it with: bgkmap simulate {recipe['preset']} -o DIR && {map_command(recipe, ['DIR/scans'])}")
    else:
        inputs = [locate.datasets_dir() / rel for rel in recipe["inputs"]]
        print(f"map it with: {map_command(recipe, [inputs[0] / 'NN'] if recipe.get('structure') == 'kitti' else inputs)}")


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("action", choices=["list", "show", "check", "prepare"])
    parser.add_argument("names", nargs="*")
    parser.add_argument("--all", action="store_true", help="check every recipe (campus only when named: 1 GB of scans)")
    parser.add_argument("--bgkmap", help="the bgkmap binary: also count the scans it reads")
    parser.add_argument("--work", help="folder for simulated datasets and count reports (default: a temporary one)")
    parser.add_argument("--from", dest="source", help="prepare: the download")
    args = parser.parse_args()
    folder = locate.datasets_dir()
    try:
        if args.action == "list":
            for name in all_names():
                recipe = load(name)
                where = ("simulated by bgkmap" if recipe["kind"] == "generated" else
                         "present" if all((folder / rel).exists() for rel in recipe["inputs"]) else "missing")
                print(f"{name:20} {recipe['kind']:9} {where:20} {recipe['title']}")
            return 0
        if args.action == "show":
            for name in args.names:
                show(name)
            return 0
        if args.action == "prepare":
            if len(args.names) != 1 or not args.source:
                raise Failed("recipe: prepare takes one NAME and --from DOWNLOAD")
            prepare(args.names[0], args.source, folder)
            args.names = args.names[:1]
    except (Failed, locate.Missing) as e:
        print(e, file=sys.stderr)
        return 1
    except OSError as e:  # e.g. a read-only datasets folder for prepare
        print(f"recipe: {e}", file=sys.stderr)
        return 1
    names = [n for n in all_names() if load(n).get("in_check_all", True)] if args.all else args.names
    if not names:
        parser.error("check needs NAME... or --all")
    failed = 0
    with tempfile.TemporaryDirectory(prefix="bgkmap-recipe-") as tmp:
        work = pathlib.Path(args.work) if args.work else pathlib.Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        for name in names:
            try:
                check(name, folder, args.bgkmap, work)
            except (Failed, locate.Missing) as e:
                print(e, file=sys.stderr)
                failed += 1
            except OSError as e:
                print(f"recipe: {name}: {e}", file=sys.stderr)
                failed += 1
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
