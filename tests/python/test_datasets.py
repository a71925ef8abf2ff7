"""datasets/: the locator and the recipes against the shared copies, missing data, damaged and
hand-made files; the results scripts with datasets missing."""
import json
import os
import pathlib
import shutil
import struct
import subprocess
import sys

import pytest

from conftest import locate, running_in_ci
from scan_files import write_scan_graph

SOURCE = pathlib.Path(__file__).resolve().parents[2]
RECIPE = SOURCE / "datasets" / "recipe.py"
LOCATE = SOURCE / "datasets" / "locate.py"

# What bgkmap build --method counting reads from the shared copies (scans, points), measured once
# by hand with the CLI; the recipes must agree.
SHARED = {
    "sim_structured": ("sim_structured", 13, 12, 42000),
    "intel": ("carmen/intel-corrected.log.gz", 1, 910, 163800),
    "freiburg079_log": ("carmen/freiburg-079-corrected.log.gz", 1, 4791, 1724760),
    "octomap_samples": ("octomap_samples/spherical_scan.graph", 2, 1, 10201),
}
DOWNLOADS = {
    "sim_unstructured": "sim_unstructured",
    "fr079_corridor_3d": "octomap_3d/fr079_corridor.graph",
    "freiburg_campus_3d": "octomap_3d/freiburg_campus.graph",
    "new_college_3d": "octomap_3d/new_college.graph",
    "kitti_odometry": "kitti",
}


def run(args, datasets, **kwargs):
    env = dict(os.environ, BGKMAP_DATASETS=str(datasets))
    return subprocess.run([str(a) for a in args], capture_output=True, text=True, env=env, **kwargs)


def recipe(datasets, *args):
    return run([sys.executable, RECIPE, *args], datasets)


def one_line(text):
    lines = text.strip().splitlines()
    assert len(lines) == 1, text
    return lines[0]


@pytest.fixture(scope="module")
def shared_folder():
    return locate.datasets_dir(os.environ.get("BGKMAP_DEFAULT_DATASETS_DIR"))


def require_shared(folder, relative):
    if not (folder / relative).exists():
        message = f"{folder / relative} missing (set BGKMAP_DATASETS)"
        if running_in_ci():
            pytest.fail(message)
        pytest.skip(message)


def write_kitti_root(root, sequence, scans, poses):
    velodyne = root / "sequences" / sequence / "velodyne"
    velodyne.mkdir(parents=True)
    for i in range(scans):
        (velodyne / f"{i:06d}.bin").write_bytes(struct.pack("<12f", *([1.0 + i, 2.0, 0.5, 0.1] * 3)))
    identity = "1 0 0 0 0 1 0 0 0 0 1 0"
    (root / "sequences" / sequence / "calib.txt").write_text(f"P0: {identity}\nTr: {identity}\n")
    (root / "poses").mkdir(exist_ok=True)
    (root / "poses" / f"{sequence}.txt").write_text("".join(f"1 0 0 {i} 0 1 0 0 0 0 1 0\n" for i in range(poses)))


def test_locate_prints_the_environment_folder_else_the_one_beside_the_checkout(tmp_path):
    assert run([sys.executable, LOCATE], tmp_path).stdout.strip() == str(tmp_path)
    env = {k: v for k, v in os.environ.items() if k != "BGKMAP_DATASETS"}
    beside = subprocess.run([sys.executable, LOCATE], capture_output=True, text=True, env=env).stdout.strip()
    assert pathlib.Path(beside) == SOURCE.parent / "shared" / "datasets"
    r = run([sys.executable, LOCATE, "--require", "carmen/x.log", "--tag", "t"], tmp_path)
    assert r.returncode == 1 and r.stdout == ""
    assert one_line(r.stderr).startswith(f"t: carmen/x.log is missing from {tmp_path} ")


@pytest.mark.parametrize("name", sorted(SHARED))
def test_shared_copies_match_their_recipe(name, cli, shared_folder):
    relative, files, scans, points = SHARED[name]
    require_shared(shared_folder, relative)
    r = recipe(shared_folder, "check", name, "--bgkmap", cli)
    assert r.returncode == 0, r.stderr
    assert f"{name}: SHA-256 of {files} file{'s' * (files != 1)} as expected" in r.stdout
    said = f"{scans:,} scan{'s' * (scans != 1)}, {points:,} points (as expected)"
    assert f"{name}: bgkmap build reads {said}" in r.stdout
    assert f"bgkmap build {shared_folder / relative} -o {name}.bgk" in r.stdout
    assert r.stdout.strip().endswith(f"{name}: ok")


@pytest.mark.parametrize("name", sorted(SHARED) + sorted(DOWNLOADS))
def test_a_recipe_in_an_empty_folder_names_what_is_missing(name, tmp_path):
    r = recipe(tmp_path, "check", name)
    assert r.returncode == 1
    relative = SHARED[name][0] if name in SHARED else DOWNLOADS[name]
    assert one_line(r.stderr).startswith(f"recipe: {name}: {relative} is missing from {tmp_path} ")


@pytest.mark.parametrize("name", sorted(DOWNLOADS))
def test_a_download_absent_from_the_shared_folder_is_one_line(name, shared_folder):
    if (shared_folder / DOWNLOADS[name]).exists():
        pytest.skip(f"{name} is present in {shared_folder}")
    r = recipe(shared_folder, "check", name)
    assert r.returncode == 1
    assert f"{DOWNLOADS[name]} is missing" in one_line(r.stderr)


def test_a_damaged_copy_is_refused_naming_the_file(tmp_path, shared_folder):
    require_shared(shared_folder, "octomap_samples")
    shutil.copytree(shared_folder / "octomap_samples", tmp_path / "octomap_samples")
    damaged = tmp_path / "octomap_samples" / "geb079.bt"
    os.chmod(damaged, 0o644)
    data = bytearray(damaged.read_bytes())
    data[1000] ^= 1
    damaged.write_bytes(bytes(data))
    r = recipe(tmp_path, "check", "octomap_samples")
    assert r.returncode == 1
    line = one_line(r.stderr)
    assert f"{damaged}: SHA-256" in line and "7663c2466e2fe335" in line


def test_a_scan_graph_is_counted_as_bgkmap_reads_it(cli, tmp_path):
    graph = tmp_path / "octomap_3d" / "freiburg_campus.graph"
    write_scan_graph(graph, [((0.0, 0.0, 1.0), [(1.0, 0.0, 0.0), (2.0, 1.0, 0.0)]),
                             ((1.0, 0.0, 1.0), [(1.0, 1.0, 0.5), (3.0, 0.0, 0.0), (2.0, -1.0, 0.0)])])
    r = recipe(tmp_path, "check", "freiburg_campus_3d", "--bgkmap", cli)
    assert r.returncode == 0, r.stderr
    assert "freiburg_campus_3d: the scan graph holds 2 scans, 5 points (no expected count known)" in r.stdout
    assert "freiburg_campus_3d: bgkmap build reads 2 scans, 5 points (no expected count known)" in r.stdout

    graph.write_bytes(graph.read_bytes()[:-10])
    r = recipe(tmp_path, "check", "freiburg_campus_3d")
    assert r.returncode == 1
    assert one_line(r.stderr) == f"recipe: {graph}: node 1 claims 3 points, more than the file holds"


def test_a_scan_graph_of_another_scan_count_is_refused(tmp_path):
    graph = tmp_path / "source.graph"
    write_scan_graph(graph, [((0.0, 0.0, 1.0), [(1.0, 0.0, 0.0)])] * 2)
    r = recipe(tmp_path, "prepare", "fr079_corridor_3d", "--from", graph)
    assert (tmp_path / "octomap_3d" / "fr079_corridor.graph").read_bytes() == graph.read_bytes()
    assert r.returncode == 1
    assert one_line(r.stderr) == ("recipe: fr079_corridor_3d: the scan graph holds 2 scans where the recipe expects 66 "
                                  "(T-RO 2019 Table II; checksums unknown: no copy here)")


def test_a_kitti_download_is_linked_with_its_poses_and_counted(cli, tmp_path):
    root, datasets = tmp_path / "kitti_root", tmp_path / "datasets"
    write_kitti_root(root, "99", scans=2, poses=2)
    r = recipe(datasets, "prepare", "kitti_odometry", "--from", root)
    assert r.returncode == 0, r.stderr
    assert (datasets / "kitti" / "99" / "poses.txt").resolve() == (root / "poses" / "99.txt").resolve()
    r = recipe(datasets, "check", "kitti_odometry", "--bgkmap", cli)
    assert r.returncode == 0, r.stderr
    assert "kitti_odometry 99: the sequence holds 2 scans, 6 points (no expected count known)" in r.stdout
    assert "kitti_odometry 99: bgkmap build reads 2 scans, 6 points (no expected count known)" in r.stdout


def test_a_kitti_sequence_that_does_not_fit_is_one_line(tmp_path):
    root, datasets = tmp_path / "kitti_root", tmp_path / "datasets"
    write_kitti_root(root, "00", scans=2, poses=2)
    r = recipe(datasets, "prepare", "kitti_odometry", "--from", root)
    assert r.returncode == 1
    assert one_line(r.stderr).startswith("recipe: kitti_odometry 00: the sequence holds 2 scans where the recipe expects 4,541")
    (root / "poses" / "00.txt").write_text("1 0 0 0 0 1 0 0 0 0 1 0\n" * 3)
    r = recipe(datasets, "check", "kitti_odometry")
    assert r.returncode == 1
    assert one_line(r.stderr) == f"recipe: {datasets / 'kitti' / '00' / 'poses.txt'}: 3 poses for 2 scans in velodyne/ (one pose a scan)"


def test_prepare_refuses_the_default_shared_folder(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "BGKMAP_DATASETS"}
    r = subprocess.run([sys.executable, RECIPE, "prepare", "kitti_odometry", "--from", tmp_path / "absent"],
                       capture_output=True, text=True, env=env)
    assert r.returncode == 1
    assert one_line(r.stderr).startswith("recipe: prepare writes into $BGKMAP_DATASETS: set it to a datasets folder")


def test_pcd_scans_without_their_origins_are_refused(tmp_path):
    source = tmp_path / "la3dm"
    source.mkdir()
    for i in (1, 2):
        (source / f"sim_unstructured_{i}.pcd").write_text(
            "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 1\nHEIGHT 1\n"
            "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 1\nDATA ascii\n1 2 3\n")
    r = recipe(tmp_path, "prepare", "sim_unstructured", "--from", source)
    assert r.returncode == 1
    assert one_line(r.stderr).startswith(f"recipe: {tmp_path / 'sim_unstructured'}: every scan has the VIEWPOINT 0 0 0")


@pytest.mark.parametrize("preset", ["structured", "unstructured"])
def test_a_generated_preset_is_simulated_and_counted(preset, cli, tmp_path):
    r = recipe(tmp_path, "check", preset, "--bgkmap", cli, "--work", tmp_path)
    assert r.returncode == 0, r.stderr
    assert f"{preset}: bgkmap simulate wrote 12 scans, 345,600 points (as expected)" in r.stdout
    assert f"bgkmap simulate {preset} -o DIR && bgkmap build DIR/scans -o {preset}.bgk --ds 0.1 --max-range 14" in r.stdout
    report = tmp_path / "count.json"
    subprocess.run([cli, "build", tmp_path / preset / "scans", "--max-range", "14", "--resolution", "1", "--method", "counting", "-q", "-o", tmp_path / "c.bgk",
                    "--report", report], check=True)
    counts = json.loads(report.read_text())["counts"]
    assert (counts["scans"], counts["points_read"]) == (12, 345600)


def test_results_scripts_name_each_missing_dataset_on_one_line(cli, tmp_path):
    env = dict(os.environ, BGKMAP_DATASETS=str(tmp_path), BGKMAP=cli)
    r = subprocess.run(["bash", SOURCE / "scripts" / "real_data.sh", tmp_path / "out"], capture_output=True, text=True, env=env)
    assert r.returncode == 1
    assert r.stderr.strip().splitlines() == [
        f"real_data: carmen/intel-corrected.log.gz is missing from {tmp_path} (datasets/README.md says how to get it; "
        "BGKMAP_DATASETS names another folder)",
        f"real_data: carmen/freiburg-079-corrected.log.gz is missing from {tmp_path} (datasets/README.md says how to get "
        "it; BGKMAP_DATASETS names another folder)",
        "real_data: none of the logs is in the datasets folder: nothing mapped"]
    r = subprocess.run([sys.executable, SOURCE / "bench" / "throughput_table.py", "--bgkmap", cli, "--datasets", tmp_path,
                        "--skip-campus", "--intel"], capture_output=True, text=True)
    assert r.returncode == 1
    lines = r.stderr.strip().splitlines()
    assert [line.split(" is missing")[0] for line in lines[:2]] == ["throughput: sim_structured",
                                                                    "throughput: carmen/intel-corrected.log.gz"]
    assert lines[2] == "throughput: nothing to measure (every dataset asked for is missing)"
