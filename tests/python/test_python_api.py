"""What makes the module Python's: paths as pathlib.Path, array-likes, planar Mappers, repr, help
with its real defaults, progress callbacks."""
import pathlib

import numpy as np
import pytest

import bgkmap
from conftest import FLAGS, SETTINGS, run_cli


def test_paths_may_be_pathlib_paths(mapper, scans, tmp_path):
    path = tmp_path / "m.bgk"
    mapper.save(path)
    loaded = bgkmap.load(path, backend="cpu")
    for got, want in zip(loaded.cells(), mapper.cells()):
        np.testing.assert_array_equal(got, want)
    mapper.export(tmp_path / "m.ot")
    mapper.export(tmp_path / "band.pgm", z_min=0.1, z_max=1.5)
    assert (tmp_path / "m.ot").stat().st_size > 0 and (tmp_path / "band.yaml").is_file()
    as_paths = [pathlib.Path(s) for s in scans]
    m = bgkmap.Mapper(**SETTINGS)
    assert m.insert_file(tuple(as_paths)) == len(scans)
    assert len(bgkmap.read_scans(as_paths[0])) == 1
    for got, want in zip(m.cells(), mapper.cells()):
        np.testing.assert_array_equal(got, want)
    assert bgkmap.view(path, tmp_path / "m.html")["boxes"] > 0
    report = bgkmap.build(as_paths[:1], outputs=tmp_path / "one.ot", **SETTINGS)
    assert report["counts"]["scans"] == 1 and (tmp_path / "one.ot").stat().st_size > 0
    with pytest.raises(TypeError, match="os.PathLike"):
        mapper.save(3)


def test_array_likes_are_read_as_float64(mapper):
    centres, alpha, beta = mapper.cells()
    cell = centres[np.argmax(alpha / (alpha + beta))]  # a wall cell, where the mean is far from the prior's 0.5
    want = mapper.mean(cell[None, :])
    assert want[0] > 0.9
    np.testing.assert_array_equal(mapper.mean([list(cell)]), want)
    np.testing.assert_array_equal(mapper.mean((tuple(cell),)), want)
    np.testing.assert_array_equal(mapper.mean([[1, 1, 1]]), mapper.mean(np.array([[1.0, 1.0, 1.0]])))
    for dtype in (np.int32, np.int64, np.uint16, np.float16):
        np.testing.assert_array_equal(mapper.query(np.ones((2, 3), dtype=dtype)), mapper.query(np.ones((2, 3))))
    hits = mapper.cast_rays([[0.5, 0.5, 1]], [[1, 0, 0]], max_range=20)
    np.testing.assert_array_equal(hits["distance"], mapper.cast_rays(np.array([[0.5, 0.5, 1.0]]),
                                                                     np.array([[1.0, 0, 0]]), 20.0)["distance"])
    assert bgkmap.auc([0, 1, 1, 0], [0, 1, 1, 1]) == pytest.approx(0.75)


def test_integer_points_go_in_as_their_float_values(scans):
    scan = bgkmap.read_scans(scans[0])[0]
    rounded = np.round(scan["points"]).astype(np.int64)  # a coarse scan: whole metres, a few distinct points
    a, b = bgkmap.Mapper(**SETTINGS), bgkmap.Mapper(**SETTINGS)
    a.insert(rounded, [0, 0, 1])
    b.insert(rounded.astype(np.float64), np.array([0.0, 0.0, 1.0]))
    assert a.counts()["hits"] > 20 and len(a.cells()[1]) > 1000
    for got, want in zip(a.cells(), b.cells()):
        np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize(
    "points, message",
    [
        (np.zeros((2, 3), dtype=bool), "points must hold integers or floats, got bool"),
        (np.zeros((2, 3), dtype=complex), "points must hold integers or floats, got complex128"),
        ([["a", "b", "c"]], "points must hold integers or floats, got <U1"),
        ([[0, 0, None]], "points must hold integers or floats, got object"),
    ],
)
def test_what_is_not_a_number_is_refused(points, message):
    m = bgkmap.Mapper()
    with pytest.raises(TypeError, match=message):
        m.insert(points, [0, 0, 0])
    with pytest.raises(TypeError, match=message):
        m.mean(points)


def test_a_planar_mapper_is_the_cli_2d_map(cli, scans, tmp_path):
    out = tmp_path / "cli2d.bgk"
    rc, _, err = run_cli(cli, "build", "-q", *scans, "-o", out, *FLAGS, "--2d", "--plane-z", "0.5")
    assert rc == 0, err
    m = bgkmap.Mapper(planar=True, plane_z=0.5, **SETTINGS)
    assert m.insert_file(scans) == len(scans)
    assert m.params["planar"] is True and m.params["plane_z"] == pytest.approx(0.55)  # the layer's centre
    m.save(tmp_path / "py2d.bgk")
    assert (tmp_path / "py2d.bgk").read_bytes() == out.read_bytes()
    centres, alpha, beta = m.cells()
    assert len(alpha) > 1000 and set(np.round(centres[:, 2], 6)) == {0.55}
    for got, want in zip((centres, alpha, beta), bgkmap.load(out).cells()):
        np.testing.assert_array_equal(got, want)
    assert bgkmap.Mapper(planar=True, **SETTINGS).params["plane_z"] == pytest.approx(0.05)
    assert "planar" not in bgkmap.Mapper().params
    with pytest.raises(ValueError, match="give planar=True with it"):
        bgkmap.Mapper(plane_z=1.0)


def test_repr_names_method_shape_resolution_and_cells(mapper, cli, scans, tmp_path):
    cells = len(mapper.cells()[1])
    assert repr(mapper) == f"<bgkmap.Mapper bgkl, 3-D, resolution 0.1 m, {cells} cells with evidence>"
    assert repr(bgkmap.Mapper(planar=True, resolution=0.2)) == \
        "<bgkmap.Mapper bgkl, 2-D at z=0.1 m, resolution 0.2 m, 0 cells with evidence>"
    rc, _, err = run_cli(cli, "build", "-q", scans[0], "-o", tmp_path / "c.bgk", "--method", "counting", *FLAGS)
    assert rc == 0, err
    counting = bgkmap.load(tmp_path / "c.bgk")
    assert repr(counting).startswith("<bgkmap.Mapper counting, 3-D, resolution 0.1 m, ")


def test_help_shows_the_defaults_python_takes(cli):
    doc = bgkmap.Mapper.__doc__
    for line in ("    resolution=0.1: Cell size; in [0.001, 10000] m", "    kernel='sparse': ",
                 "    ell=0.2: Kernel length scale l (m); > 0 and finite", "    frame='world': ",
                 "    apply_viewpoint=False: ", "    planar=False: A planar map",
                 "    plane_z=0.0: With --2d: a height in the layer of cells the map keeps (m); finite",
                 "    backend='auto': ", "    threads=0: "):
        assert line in doc, line
    assert "false" not in doc and "true" not in doc  # Python's False and True, not JSON's
    # Each default shown is the one a Mapper takes, and the CLI's.
    m = bgkmap.Mapper()
    for key, value in m.params.items():
        assert f"    {key}={value!r}: " in doc or key == "apply_viewpoint"
    assert "(m)" in bgkmap.Mapper.cast_rays.__doc__ and "(m)" in bgkmap.Mapper.query.__doc__


def test_frame_is_the_keyword_of_the_cli(tmp_path):
    assert bgkmap.Mapper(frame="sensor").params == bgkmap.Mapper(apply_viewpoint=True).params
    assert bgkmap.Mapper(frame="world").params == bgkmap.Mapper().params
    with pytest.raises(ValueError, match="frame must be 'world' or 'sensor', not 'camera'"):
        bgkmap.Mapper(frame="camera")
    with pytest.raises(TypeError, match="give frame or apply_viewpoint, not both"):
        bgkmap.Mapper(frame="sensor", apply_viewpoint=True)
    (tmp_path / "a.xyz").write_text("1 0 0\n")
    with pytest.raises(ValueError, match=r"frame='sensor' but the Mapper's frame is 'world'"):
        bgkmap.Mapper().insert_file(tmp_path / "a.xyz", origin=[0, 0, 0], frame="sensor")


def test_insert_file_reports_progress_in_scans(mapper, scans):
    calls = []
    m = bgkmap.Mapper(**SETTINGS)
    # The callback may read the map it watches.
    assert m.insert_file(scans, progress=lambda done, total: calls.append((done, total, m.counts()["scans"]))) == 4
    assert calls == [(0, 4, 0), (1, 4, 1), (2, 4, 2), (3, 4, 3), (4, 4, 4)]
    calls.clear()
    assert m.insert_file(scans, progress=lambda done, total: calls.append((done, total))) == 0
    assert calls == [(0, 4), (4, 4)]  # every scan already held: passed over


def test_progress_of_a_log_has_no_total_and_an_exception_stops_it(datasets):
    log = datasets / "carmen" / "intel-corrected.log.gz"
    if not log.is_file():
        pytest.skip(f"{log} is missing")
    calls = []

    def stop_at_three(done, total):
        calls.append((done, total))
        if done == 3:
            raise KeyboardInterrupt

    m = bgkmap.Mapper(backend="cpu", planar=True, max_range=8)
    with pytest.raises(KeyboardInterrupt):
        m.insert_file(log, progress=stop_at_three)
    assert [done for done, _ in calls] == [0, 1, 2, 3]
    assert 100 < calls[-1][1] < 10000  # the log's 910 scans, estimated from the bytes read so far
    assert m.counts()["scans"] == 3  # those before the exception stay
    with pytest.raises(TypeError, match="progress must be a callable"):
        m.insert_file(log, progress=3)


def test_build_reports_progress(scans, tmp_path):
    calls = []
    report = bgkmap.build(scans, outputs=tmp_path / "m.bgk", progress=lambda done, total: calls.append((done, total)),
                          **SETTINGS)
    assert report["counts"]["scans"] == 4
    assert sorted(set(calls)) == calls[:4] == [(1, 4), (2, 4), (3, 4), (4, 4)] and calls[-1] == (4, 4)

    def interrupt(done, total):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        bgkmap.build(scans, outputs=tmp_path / "stopped.bgk", progress=interrupt, **SETTINGS)
    assert not (tmp_path / "stopped.bgk").exists()
    bgkmap.build(scans[:1], outputs=tmp_path / "after.bgk", **SETTINGS)  # no callback left behind


def test_build_reports_each_phase_of_a_method(scans, tmp_path):
    """gpom: the scan read, then its prediction counted in blocks from 0, reported from its workers too."""
    calls = []
    bgkmap.build(scans[:1], method="gpom", outputs=tmp_path / "g.ot", max_range=8, ds=0.2, resolution=0.2,
                 backend="cpu", progress=lambda done, total: calls.append((done, total)))
    assert calls[0] == (1, 1)
    start = next(i for i, (done, total) in enumerate(calls) if done == 0)
    blocks = calls[start][1]
    prediction = calls[start:]
    assert blocks > 10 and {total for _, total in prediction} == {blocks}
    assert [done for done, _ in prediction] == sorted(done for done, _ in prediction)
    assert prediction[-1] == (blocks, blocks) and len(prediction) > 10
