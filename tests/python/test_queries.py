"""Ray casts, box and occupied-cell queries from Python: against `bgkmap query`, a plain walk that
samples each ray every 2 mm, and numpy filters of every cell with evidence."""
import numpy as np
import pytest

import bgkmap
from conftest import run_cli


def random_rays(n, seed):
    """Rays from around sim_structured's sensor origins, mostly level."""
    rng = np.random.default_rng(seed)
    origins = np.column_stack([rng.uniform(0.5, 6, n), rng.uniform(0.5, 4, n), rng.uniform(0.2, 1.5, n)])
    directions = rng.normal(size=(n, 3)) * [1, 1, 0.3]
    return origins, directions


@pytest.mark.parametrize("unknown", ["stop", "pass"])
def test_cast_rays_equal_the_cli(cli, cli_map, mapper, tmp_path, unknown):
    origins, directions = random_rays(300, 1)
    ranges = np.where(np.arange(300) % 3 == 0, 2.5, 0.0)
    rays_file = tmp_path / "rays.txt"
    np.savetxt(rays_file, np.column_stack([origins, directions, ranges]), fmt="%.17g")
    rc, out, err = run_cli(cli, "query", cli_map, "--rays", rays_file, "--unknown", unknown)
    assert rc == 0, err
    rows = [line.split() for line in out.splitlines()]
    got = mapper.cast_rays(origins, directions, ranges, unknown=unknown)
    assert got["hit"].dtype == np.bool_ and got["centres"].shape == (300, 3)
    np.testing.assert_array_equal(got["hit"], [r[0] == "1" for r in rows])
    np.testing.assert_allclose(got["centres"], [[float(v) for v in r[1:4]] for r in rows], rtol=1e-8)
    np.testing.assert_allclose(got["distance"], [float(r[4]) for r in rows], rtol=1e-8)
    states = {bgkmap.UNKNOWN: "unknown", bgkmap.FREE: "free", bgkmap.OCCUPIED: "occupied"}
    stops = {bgkmap.STOP_OCCUPIED: "occupied", bgkmap.STOP_UNKNOWN: "unknown", bgkmap.STOP_MAX_RANGE: "max_range",
             bgkmap.STOP_MAP_END: "map_end"}
    assert [states[s] for s in got["state"]] == [r[5] for r in rows]
    assert [stops[s] for s in got["stop"]] == [r[6] for r in rows]
    assert got["hit"].sum() > (100 if unknown == "pass" else 0)


def test_cast_rays_against_a_sampled_walk(mapper):
    """Sampled every 2 mm, a ray meets no occupied cell before the distance cast_rays reports, and just
    past it is inside the cell it reports; a ray that hit nothing within its range meets none."""
    origins, directions = random_rays(200, 2)
    got = mapper.cast_rays(origins, directions, 6.0, "pass")
    units = directions / np.linalg.norm(directions, axis=1, keepdims=True)
    resolution = mapper.params["resolution"]
    for i in range(len(origins)):
        end = got["distance"][i] if got["hit"][i] else 6.0
        t = np.arange(0.0, end - 1e-6, 0.002)
        samples = origins[i] + t[:, None] * units[i]
        assert not np.any(mapper.state(samples) == bgkmap.OCCUPIED), i
        if got["hit"][i]:
            inside = origins[i] + (end + 1e-7) * units[i]
            np.testing.assert_array_equal(np.floor(inside / resolution), np.floor(got["centres"][i] / resolution))
            assert mapper.state(inside[None, :])[0] == bgkmap.OCCUPIED
    assert got["hit"].sum() > 80


def sorted_rows(centres, *columns):
    order = np.lexsort(centres.T[::-1])
    return (centres[order],) + tuple(c[order] for c in columns)


def test_cells_in_box_and_occupied_cells_equal_numpy_filters(mapper):
    centres, alpha, beta = mapper.cells()
    state = mapper.state(centres)
    lo, hi = np.array([1.0, 0.5, 0.0]), np.array([4.0, 3.2, 1.2])
    inside = np.all((centres >= lo) & (centres <= hi), axis=1)
    got = mapper.cells_in_box(lo, hi)
    assert len(got["alpha"]) == inside.sum() > 1000
    for g, want in zip(sorted_rows(got["centres"], got["alpha"], got["beta"], got["state"]),
                       sorted_rows(centres[inside], alpha[inside], beta[inside], state[inside])):
        np.testing.assert_array_equal(g, want)

    every = mapper.cells_in_box(lo, hi, include_unobserved=True)
    per_axis = [np.sum((np.arange(-100, 100) + 0.5) * 0.1 >= l - 1e-10) -
                np.sum((np.arange(-100, 100) + 0.5) * 0.1 > h + 1e-10) for l, h in zip(lo, hi)]
    assert len(every["alpha"]) == np.prod(per_axis)
    unobserved = every["alpha"] == np.float32(0.001)
    assert np.all(every["state"][unobserved & (every["beta"] == np.float32(0.001))] == bgkmap.UNKNOWN)

    occupied = mapper.occupied_cells(lo, hi)
    mask = inside & (state == bgkmap.OCCUPIED)
    assert len(occupied["alpha"]) == mask.sum() > 50
    np.testing.assert_array_equal(sorted_rows(occupied["centres"])[0], sorted_rows(centres[mask])[0])
    whole = mapper.occupied_cells()
    np.testing.assert_array_equal(sorted_rows(whole["centres"])[0], sorted_rows(centres[state == bgkmap.OCCUPIED])[0])


def test_bad_rays_and_boxes_are_refused(mapper):
    origins, directions = random_rays(3, 3)
    with pytest.raises(ValueError, match=r"ray 1: the ray's direction is zero"):
        mapper.cast_rays(origins, np.array([[1.0, 0, 0], [0, 0, 0], [0, 1.0, 0]]))
    with pytest.raises(ValueError, match=r"directions must have as many rows as origins \(3\), got \(2, 3\)"):
        mapper.cast_rays(origins, directions[:2])
    with pytest.raises(ValueError, match=r"max_range must be a number or an array of shape \(3,\)"):
        mapper.cast_rays(origins, directions, np.ones(2))
    with pytest.raises(ValueError, match=r"ray 0: max range -1 is not a length"):
        mapper.cast_rays(origins, directions, -1.0)
    with pytest.raises(ValueError, match=r"accepted: stop, pass"):
        mapper.cast_rays(origins, directions, unknown="ignore")
    with pytest.raises(TypeError, match=r"origins must hold integers or floats, got bool"):
        mapper.cast_rays(origins.astype(bool), directions)
    with pytest.raises(ValueError, match=r"minimum must not exceed its maximum"):
        mapper.cells_in_box([1.0, 0, 0], [0.0, 1, 1])
    with pytest.raises(TypeError, match=r"give both corners"):
        mapper.occupied_cells([0.0, 0, 0])
    with pytest.raises(ValueError, match=r"lo holds NaN or Inf"):
        mapper.cells_in_box([np.nan, 0, 0], [1.0, 1, 1])


def test_a_box_of_more_cells_than_memory_holds_is_refused(mapper):
    with pytest.raises(RuntimeError, match=r"the box's cells needs .* give a smaller box"):
        mapper.cells_in_box([-1e5, -1e5, -1e5], [1e5, 1e5, 1e5], include_unobserved=True)
    assert len(mapper.cells_in_box([-1e5, -1e5, -1e5], [1e5, 1e5, 1e5])["alpha"]) == len(mapper.cells()[1])
