"""bgkmap.Mapper against the CLI on the same scans, and its handling of bad arrays."""
import json

import numpy as np
import pytest

import bgkmap
from conftest import FLAGS, SETTINGS, run_cli


def test_cells_equal_the_cli_map_bit_for_bit(cli_map, mapper, tmp_path):
    mapper.save(str(tmp_path / "py.bgk"))
    # The same inputs recorded as held (for --resume), so the same file.
    assert (tmp_path / "py.bgk").read_bytes() == cli_map.read_bytes()
    centres, alpha, beta = bgkmap.load(str(tmp_path / "py.bgk")).cells()
    c2, a2, b2 = bgkmap.load(str(cli_map)).cells()
    assert len(alpha) > 50000
    assert centres.shape == (len(alpha), 3)
    np.testing.assert_array_equal(centres, c2)
    np.testing.assert_array_equal(alpha, a2)
    np.testing.assert_array_equal(beta, b2)
    assert mapper.counts()["cells_with_evidence"] == len(alpha)
    for got, want in zip(mapper.cells(), (centres, alpha, beta)):
        np.testing.assert_array_equal(got, want)


def test_query_equals_cli_query(cli, cli_map, mapper, tmp_path):
    centres, _, _ = mapper.cells()
    rng = np.random.default_rng(7)
    points = np.vstack([centres[rng.choice(len(centres), 300, replace=False)], [[100.0, 100.0, 100.0]]])
    points_file = tmp_path / "points.txt"
    np.savetxt(points_file, points, fmt="%.17g")
    rc, out, err = run_cli(cli, "query", cli_map, "--points", points_file)
    assert rc == 0, err
    rows = [line.split() for line in out.splitlines()]
    cli_alpha = np.array([float(r[3]) for r in rows])
    cli_beta = np.array([float(r[4]) for r in rows])
    cli_state = [r[7] for r in rows]
    alpha, beta = mapper.query(points)
    # The CLI prints 9 significant digits: exact for the cells' float32 values.
    np.testing.assert_array_equal(alpha.astype(np.float32), cli_alpha.astype(np.float32))
    np.testing.assert_array_equal(beta.astype(np.float32), cli_beta.astype(np.float32))
    names = {bgkmap.UNKNOWN: "unknown", bgkmap.FREE: "free", bgkmap.OCCUPIED: "occupied"}
    assert [names[s] for s in mapper.state(points)] == cli_state
    np.testing.assert_array_equal(mapper.mean(points), alpha / (alpha + beta))
    s = alpha + beta
    np.testing.assert_allclose(mapper.variance(points), alpha * beta / (s * s * (s + 1)), rtol=1e-15)
    assert alpha[-1] == np.float32(0.001) and beta[-1] == np.float32(0.001)  # never observed: the prior


def test_arrays_in_equal_files_in(mapper, scans):
    m = bgkmap.Mapper(**SETTINGS)
    for scan in bgkmap.read_scans(scans):
        assert scan["points"].dtype == np.float32 and scan["points"].shape[1] == 3
        m.insert(scan["points"], scan["origin"])
    for got, want in zip(m.cells(), mapper.cells()):
        np.testing.assert_array_equal(got, want)


def test_pose_transforms_sensor_frame_points(scans):
    scan = bgkmap.read_scans(scans[0])[0]
    world, origin = scan["points"].astype(np.float64), scan["origin"]
    # A quarter turn about z and a shift: exact in floating point, so both maps must agree exactly.
    pose = np.array([[0, -1, 0, origin[0]], [1, 0, 0, origin[1]], [0, 0, 1, origin[2]], [0, 0, 0, 1]], float)
    local = (world - origin) @ pose[:3, :3]  # R^T (p - t)
    a, b = bgkmap.Mapper(**SETTINGS), bgkmap.Mapper(**SETTINGS)
    a.insert(world, origin)
    b.insert(local, pose=pose)
    for got, want in zip(b.cells(), a.cells()):
        np.testing.assert_array_equal(got, want)


def test_nan_points_are_dropped_and_counted_like_the_cli(scans):
    scan = bgkmap.read_scans(scans[0])[0]
    points = scan["points"].copy()
    clean = bgkmap.Mapper(**SETTINGS)
    clean.insert(points, scan["origin"])
    dirty = bgkmap.Mapper(**SETTINGS)
    with_nan = np.vstack([points, [[np.nan, 0, 0], [0, np.inf, 0]]]).astype(np.float32)
    dirty.insert(with_nan, scan["origin"])
    assert dirty.counts()["dropped_nonfinite"] == 2
    assert dirty.counts()["points_read"] == len(points) + 2
    for got, want in zip(dirty.cells(), clean.cells()):
        np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize(
    "points, error, message",
    [
        (np.zeros((5, 2)), ValueError, r"points must have shape \(N, 3\), got \(5, 2\)"),
        (np.zeros(3), ValueError, r"points must have shape \(N, 3\), got \(3,\)"),
        ([[0, 0]], ValueError, r"points must have shape \(N, 3\), got \(1, 2\)"),
        (np.zeros((5, 3), dtype=bool), TypeError, "points must hold integers or floats, got bool"),
    ],
)
def test_bad_point_arrays_are_refused(points, error, message):
    m = bgkmap.Mapper()
    with pytest.raises(error, match=message):
        m.insert(points, np.zeros(3))
    with pytest.raises(error, match=message):
        m.query(points)


def test_arrays_too_large_to_convert_raise_memory_error():
    # A broadcast view needs a copy as float64 rows; pybind11 gave a null array when it could not
    # be made, which was dereferenced (a crash).
    huge = np.broadcast_to(np.zeros(3, dtype=np.float32), (2**40, 3))
    m = bgkmap.Mapper(**SETTINGS)
    with pytest.raises(MemoryError):
        m.insert(huge, origin=[0, 0, 0])
    with pytest.raises(MemoryError):
        m.mean(huge)
    assert m.counts()["scans"] == 0


def test_numpy_scalars_are_taken_as_parameters():
    m = bgkmap.Mapper(resolution=np.float32(0.2), block_depth=np.int64(3), max_range=np.float64(8))
    assert m.params["resolution"] == pytest.approx(0.2)
    assert m.params["block_depth"] == 3
    with pytest.raises(TypeError, match="parameter 'resolution' has the wrong type"):
        bgkmap.Mapper(resolution=np.array([0.2, 0.3]))


def test_bad_origins_poses_and_queries_are_refused():
    m = bgkmap.Mapper()
    points = np.ones((4, 3))
    with pytest.raises(ValueError, match=r"origin must have shape \(3,\), got \(2,\)"):
        m.insert(points, np.zeros(2))
    with pytest.raises(ValueError, match="origin holds NaN or Inf"):
        m.insert(points, np.array([0, np.nan, 0]))
    with pytest.raises(TypeError, match="exactly one of origin"):
        m.insert(points)
    with pytest.raises(ValueError, match="not orthonormal"):
        m.insert(points, pose=np.diag([2.0, 1, 1, 1]))
    with pytest.raises(ValueError, match="reflection"):
        m.insert(points, pose=np.diag([1.0, 1, -1, 1]))
    with pytest.raises(ValueError, match=r"last row must be \[0, 0, 0, 1\]"):
        m.insert(points, pose=np.ones((4, 4)))
    with pytest.raises(ValueError, match=r"points\[1\] is not finite"):
        m.query(np.array([[0, 0, 0], [np.nan, 0, 0]]))
    for far in ([1e30, 0, 0], [0, -3e9, 0]):  # wrapped the 32-bit keys
        with pytest.raises(ValueError, match=r"points\[1\] lies beyond the map's key range"):
            m.query(np.array([[0, 0, 0], far]))
    assert m.counts()["scans"] == 0  # nothing refused reached the map


def test_parameters_follow_the_cli(cli, scans, tmp_path):
    assert bgkmap.Mapper().params == bgkmap.Mapper(resolution=0.1, ell=0.2).params
    with pytest.raises(TypeError, match="unknown parameter 'resolutoin'"):
        bgkmap.Mapper(resolutoin=0.1)
    with pytest.raises(ValueError) as python_error:
        bgkmap.Mapper(ell=-1.0)
    rc, _, err = run_cli(cli, "build", scans[0], "-o", tmp_path / "x.bgk", "--ell", "-1")
    assert rc != 0
    # The same refusal, each naming the parameter as its user spells it.
    assert err.strip() == "bgkmap: error: --" + str(python_error.value)
    assert str(python_error.value) == "ell must be > 0 and finite"
    assert "ell=0.2" in bgkmap.Mapper.__doc__ and "max_range=0.0" in bgkmap.Mapper.__doc__


def test_file_errors_keep_the_cli_message(cli, tmp_path):
    missing = tmp_path / "missing.pcd"
    rc, _, err = run_cli(cli, "build", missing, "-o", tmp_path / "x.bgk")
    assert rc != 0
    with pytest.raises(bgkmap.InputError) as e:
        bgkmap.Mapper().insert_file(str(missing))
    assert err.strip() == "bgkmap: error: " + str(e.value)
    assert isinstance(e.value, ValueError)
    with pytest.raises(bgkmap.InputError, match="missing.bgk"):
        bgkmap.load(str(tmp_path / "missing.bgk"))


def test_save_load_export(mapper, tmp_path):
    mapper.save(str(tmp_path / "m.bgk"))
    loaded = bgkmap.load(str(tmp_path / "m.bgk"), backend="cpu")
    assert loaded.params == mapper.params
    loaded.export(str(tmp_path / "m.ot"))
    loaded.export(str(tmp_path / "m.bt"))
    assert (tmp_path / "m.ot").read_bytes().startswith(b"# Octomap OcTree file\n# bgkmap ot-values classified\n")
    assert (tmp_path / "m.bt").read_bytes().startswith(b"# Octomap OcTree binary file")
    loaded.export(str(tmp_path / "mean.ot"), ot_values="mean")
    mean = (tmp_path / "mean.ot").read_bytes()
    assert mean.startswith(b"# Octomap OcTree file\n# bgkmap ot-values mean\n")
    assert len(mean) > (tmp_path / "m.ot").stat().st_size  # the cells the map calls unknown too
    with pytest.raises(ValueError, match="ot-values 'median'"):
        loaded.export(str(tmp_path / "x.ot"), ot_values="median")
    with pytest.raises(bgkmap.InputError, match="m.png"):
        loaded.export(str(tmp_path / "m.png"))


def test_export_for_navigation_stacks_is_the_cli_export(cli, mapper, tmp_path):
    """Mapper.export by extension writes what `bgkmap export` writes from the same map, band included."""
    mapper.save(str(tmp_path / "m.bgk"))
    mapper.export(str(tmp_path / "py.pgm"))
    mapper.export(str(tmp_path / "py.ply"))
    mapper.export(str(tmp_path / "py_band.pgm"), z_min=0.1, z_max=1.5)
    rc, _, err = run_cli(cli, "export", tmp_path / "m.bgk", "-o", tmp_path / "cli.pgm", "-o", tmp_path / "cli.ply")
    assert rc == 0, err
    rc, _, err = run_cli(cli, "export", tmp_path / "m.bgk", "-o", tmp_path / "cli_band.pgm", "--z-min", "0.1",
                         "--z-max", "1.5")
    assert rc == 0, err
    for py, cli_name in (("py.pgm", "cli.pgm"), ("py.ply", "cli.ply"), ("py_band.pgm", "cli_band.pgm")):
        assert (tmp_path / py).read_bytes() == (tmp_path / cli_name).read_bytes(), py
    assert (tmp_path / "py.yaml").read_text() == (tmp_path / "cli.yaml").read_text().replace("cli.pgm", "py.pgm")
    assert (tmp_path / "py.pgm").read_bytes() != (tmp_path / "py_band.pgm").read_bytes()
    # One vertex per occupied cell.
    centres, _, _ = mapper.cells()
    occupied = int((mapper.state(centres) == bgkmap.OCCUPIED).sum())
    assert occupied > 1000
    assert f"element vertex {occupied}\n".encode() in (tmp_path / "py.ply").read_bytes()[:400]
    with pytest.raises(ValueError, match="z_min and z_max go together"):
        mapper.export(str(tmp_path / "x.pgm"), z_min=0.1)
    with pytest.raises(ValueError, match="a .pgm only"):
        mapper.export(str(tmp_path / "x.ply"), z_min=0.1, z_max=1.5)
    assert not (tmp_path / "x.pgm").exists() and not (tmp_path / "x.ply").exists()


def test_a_loaded_map_passes_over_the_scans_it_holds(cli, cli_map, scans, tmp_path):
    """load() then insert_file() continues as `build --resume`: the held scans are not added twice."""
    half = bgkmap.Mapper(**SETTINGS)
    assert half.insert_file(scans[:2]) == 2
    half.save(str(tmp_path / "half.bgk"))
    rc, out, err = run_cli(cli, "info", "--json", tmp_path / "half.bgk")
    assert rc == 0, err
    assert [h["path"] for h in json.loads(out)["held_inputs"]] == scans[:2]
    loaded = bgkmap.load(str(tmp_path / "half.bgk"), backend="cpu")
    assert loaded.insert_file(scans) == len(scans) - 2
    assert loaded.insert_file(scans[1]) == 0
    loaded.save(str(tmp_path / "whole.bgk"))
    assert (tmp_path / "whole.bgk").read_bytes() == cli_map.read_bytes()
    # And the CLI resumes the saved half as its own.
    rc, _, err = run_cli(cli, "build", "-q", *scans, "-o", tmp_path / "resumed.bgk", "--resume", tmp_path / "half.bgk",
                         *FLAGS)
    assert rc == 0, err
    assert (tmp_path / "resumed.bgk").read_bytes() == cli_map.read_bytes()


def test_maps_of_other_methods_are_not_continued(cli, scans, tmp_path):
    for method in ("counting", "bgk"):
        out = tmp_path / f"{method}.bgk"
        rc, _, err = run_cli(cli, "build", "-q", *scans[:2], "-o", out, "--method", method, *FLAGS)
        assert rc == 0, err
        loaded = bgkmap.load(str(out))  # read: its cells and queries
        assert len(loaded.cells()[1]) > 1000
        with pytest.raises(ValueError, match=f"built by --method {method}: a Mapper continues BGK-L maps only"):
            loaded.insert_file(scans)
        with pytest.raises(ValueError, match=f"built by --method {method}"):
            loaded.insert(np.ones((3, 3)), np.zeros(3))
        loaded.save(str(tmp_path / "again.bgk"))  # still that method's map
        rc, out_text, _ = run_cli(cli, "info", "--json", tmp_path / "again.bgk")
        assert json.loads(out_text)["method"] == method
        rc, _, err = run_cli(cli, "build", "-q", *scans, "-o", tmp_path / "x.bgk", "--resume", out, *FLAGS)
        assert rc == 1
        assert f"built by --method {method}: --resume continues a BGK-L map" in err


def test_a_scan_refused_for_memory_leaves_the_map_and_counts(scans):
    m = bgkmap.Mapper(**SETTINGS)
    m.insert_file(scans[0])
    before, cells = m.counts(), m.cells()
    rng = np.random.default_rng(1)
    bgkmap.set_max_memory("1M")
    try:
        with pytest.raises(RuntimeError, match="--max-memory"):
            m.insert(rng.uniform(-20, 20, (20000, 3)), np.zeros(3))
    finally:
        bgkmap.set_max_memory()
    assert m.counts() == before
    for got, want in zip(m.cells(), cells):
        np.testing.assert_array_equal(got, want)
    assert {"dropped_out_of_key_range", "dropped_beyond_reach"} <= set(before)


def test_insert_file_takes_the_pose_rule_and_frame(tmp_path):
    """An XYZ scan under a rotated --poses line: refused until its frame is said; 'sensor' turns it."""
    (tmp_path / "a.xyz").write_text("1 0 0\n2 0 0\n")
    (tmp_path / "poses.txt").write_text("0 5 0 1 0 0 0.70710678 0.70710678\n")  # 90 deg about z
    with pytest.raises(bgkmap.InputError, match=r"poses.txt: line 1: a rotated pose .* give --frame world or --frame sensor"):
        bgkmap.read_scans(str(tmp_path / "a.xyz"), poses=str(tmp_path / "poses.txt"))
    (scan,) = bgkmap.read_scans(str(tmp_path / "a.xyz"), poses=str(tmp_path / "poses.txt"), frame="world")
    np.testing.assert_array_equal(scan["origin"], [5, 0, 1])
    with pytest.raises(ValueError, match="apply_viewpoint=False"):
        bgkmap.Mapper(backend="cpu").insert_file(str(tmp_path / "a.xyz"), poses=str(tmp_path / "poses.txt"), frame="sensor")
    sensor = bgkmap.Mapper(backend="cpu", apply_viewpoint=True, max_range=4)
    assert sensor.insert_file(str(tmp_path / "a.xyz"), poses=str(tmp_path / "poses.txt")) == 1
    world = bgkmap.Mapper(backend="cpu", max_range=4)
    world.insert(np.array([[5.0, 1.0, 1.0], [5.0, 2.0, 1.0]]), np.array([5.0, 0.0, 1.0]))  # R p + t
    hit = np.array([[5.05, 2.05, 1.05]])
    (alpha, beta), (want_alpha, want_beta) = sensor.query(hit), world.query(hit)
    assert want_alpha[0] > 0.01  # prior 0.001: the cell of the turned hit: transformed by the pose's rotation
    np.testing.assert_allclose(alpha, want_alpha, rtol=1e-5)  # float rounding of R p
    np.testing.assert_allclose(beta, want_beta, rtol=1e-5)


def test_a_parameter_out_of_range_is_named_by_its_keyword():
    # The ranges are the command line's (one table), the names Python's.
    with pytest.raises(ValueError, match=r"^ell must be > 0 and finite$"):
        bgkmap.Mapper(ell=-1)
    with pytest.raises(ValueError, match=r"^max_range must be > 0 and finite, or 0: no limit$"):
        bgkmap.Mapper(max_range=-2)
    with pytest.raises(ValueError, match=r"^ds 1e-30 m is below 0.01 of resolution 0.1 m"):
        bgkmap.Mapper(ds=1e-30)
    with pytest.raises(ValueError, match=r"^free_threshold must not exceed occupied_threshold$"):
        bgkmap.Mapper(free_threshold=0.9)
