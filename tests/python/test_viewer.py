"""bgkmap view in a real browser: headless Chromium loads the page and takes a screenshot.

Checks: no script error, the page draws as many cells as the map classifies occupied (counted
here from the map file, independently of the viewer's reader), and the screenshot has a coloured
region where the map is. Skipped without Chromium, failed under CI=true.
"""
import os
import re
import shutil
import subprocess
import time

import numpy as np
import pytest
from PIL import Image

import bgkmap
from conftest import run_cli, running_in_ci

BROWSER_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--use-gl=swiftshader", "--enable-unsafe-swiftshader",
                 "--hide-scrollbars", "--window-size=900,700", "--virtual-time-budget=20000"]


@pytest.fixture(scope="module")
def chromium():
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    if running_in_ci():
        pytest.fail("chromium is not installed (scripts/setup.sh installs it)")
    pytest.skip("chromium is not installed: the browser test needs it (apt-get install chromium)")


def browse(chromium, page, tmp_path, *extra, fragment=""):
    """Runs headless Chromium on the page (with "#fragment" when given); returns (seconds, stdout)."""
    t = time.monotonic()
    url = page.as_uri() + ("#" + fragment if fragment else "")
    r = subprocess.run([chromium, *BROWSER_FLAGS, *extra, url], capture_output=True, text=True, timeout=240,
                       cwd=tmp_path, env={**os.environ, "HOME": str(tmp_path)})
    assert r.returncode == 0, r.stderr[-2000:]
    return time.monotonic() - t, r.stdout


def page_state(chromium, page, tmp_path, fragment=""):
    """The data-* attributes the page's script leaves on <body>, after Chromium has run it."""
    seconds, dom = browse(chromium, page, tmp_path, "--dump-dom", fragment=fragment)
    body = re.search(r"<body([^>]*)>", dom).group(1)
    state = dict(re.findall(r'data-([a-z-]+)="([^"]*)"', body))
    assert "error" not in state, state.get("error")
    assert state.get("ready") == "1", body
    return seconds, state


def screenshot(chromium, page, tmp_path):
    """The page as headless Chromium draws it: rows x columns x RGB, one pixel per CSS pixel."""
    shot = tmp_path / "shot.png"
    browse(chromium, page, tmp_path, "--screenshot=" + str(shot))
    return np.asarray(Image.open(shot).convert("RGB")).astype(int)


def coloured_share(chromium, page, tmp_path):
    """Share of the screenshot's pixels in colour: the page's background and panel are grey, the
    map's boxes are not."""
    image = screenshot(chromium, page, tmp_path)
    saturation = image.max(axis=2) - image.min(axis=2)
    return float((saturation > 60).mean())


def numbers(text):
    return [int(v) for v in text.split(",")]


def occupied_tree_leaves(path):
    """Occupied leaves of an OctoMap .ot file, read from its bytes: after the text header ("size N",
    "data") come N nodes depth first, each a float32 log-odds and a byte of child bits; a leaf has
    none, and is occupied at log-odds >= 0 (OctoMap's default threshold, 0.5)."""
    data = path.read_bytes()
    size = int(re.search(rb"\nsize (\d+)\n", data).group(1))
    start = data.index(b"\ndata\n") + len(b"\ndata\n")
    nodes = np.frombuffer(data, np.dtype([("log_odds", "<f4"), ("children", "u1")]), size, start)
    return int(np.sum((nodes["children"] == 0) & (nodes["log_odds"] >= 0)))


def test_demo_scene_in_the_browser(cli, chromium, datasets, tmp_path):
    map_file = tmp_path / "structured.bgk"
    rc, _, err = run_cli(cli, "build", "-q", datasets / "sim_structured", "-o", map_file, "--ds", "0.1",
                         "--max-range", "8")
    assert rc == 0, err
    m = bgkmap.load(str(map_file))
    centres, _, _ = m.cells()
    expected = int(np.sum(m.state(centres) == bgkmap.OCCUPIED))
    assert expected > 1000
    page = tmp_path / "map.html"
    rc, _, err = run_cli(cli, "view", map_file, "-o", page)
    assert rc == 0, err
    seconds, state = page_state(chromium, page, tmp_path)
    assert int(state["cells-drawn"]) == expected
    assert int(state["map-occupied"]) == expected
    assert int(state["cells-held"]) == int(state["map-cells"]) >= expected  # no merging under the cap
    coloured = coloured_share(chromium, page, tmp_path)
    print(f"\nview of {map_file.name}: {page.stat().st_size / 1e6:.2f} MB, {expected} cells drawn, "
          f"page script {state['load-ms']} ms, browser run {seconds:.1f} s, coloured share {coloured:.3f}")
    assert coloured > 0.02


def test_octomap_tree_whole_and_capped(cli, chromium, datasets, tmp_path):
    tree = tmp_path / "octomap.ot"
    rc, _, err = run_cli(cli, "build", "-q", datasets / "sim_structured", "-o", tree, "--method", "octomap",
                         "--max-range", "8")
    assert rc == 0, err
    expected = occupied_tree_leaves(tree)
    assert expected > 1000

    page = tmp_path / "whole.html"
    rc, _, err = run_cli(cli, "view", tree, "-o", page)
    assert rc == 0, err
    _, state = page_state(chromium, page, tmp_path)
    assert int(state["cells-drawn"]) == int(state["map-occupied"]) == expected
    assert coloured_share(chromium, page, tmp_path) > 0.02

    # Capped at 5000 boxes: cells merged 2x2x2 until under; the page still counts the map's cells.
    page = tmp_path / "capped.html"
    rc, _, err = run_cli(cli, "view", tree, "-o", page, "--max-cells", "5000")
    assert rc == 0, err
    assert "merged" in err
    _, state = page_state(chromium, page, tmp_path)
    assert int(state["map-occupied"]) == expected
    assert 0 < int(state["cells-drawn"]) <= int(state["cells-held"]) <= 5000


def test_python_view_writes_the_cli_page(cli, datasets, tmp_path):
    m = bgkmap.Mapper(resolution=0.1, ell=0.2, ds=0.1, max_range=8, backend="cpu")
    m.insert_file(str(datasets / "sim_structured" / "scan_01.pcd"))
    m.save(str(tmp_path / "m.bgk"))
    stats = bgkmap.view(str(tmp_path / "m.bgk"), str(tmp_path / "py.html"), max_cells=2000)
    rc, _, err = run_cli(cli, "view", tmp_path / "m.bgk", "-o", tmp_path / "cli.html", "--max-cells", "2000")
    assert rc == 0, err
    assert (tmp_path / "py.html").read_bytes() == (tmp_path / "cli.html").read_bytes()
    centres, _, _ = m.cells()
    assert stats["map_cells"] == int(np.sum(m.mean(centres) >= 0.5)) > 2000
    assert stats["boxes"] <= 2000 and stats["bytes"] == (tmp_path / "py.html").stat().st_size
    with pytest.raises(bgkmap.InputError, match="missing.bgk"):
        bgkmap.view(str(tmp_path / "missing.bgk"), str(tmp_path / "x.html"))
    with pytest.raises(ValueError, match="HTML"):
        bgkmap.view(tmp_path / "m.bgk", tmp_path / "m.png")
    assert not (tmp_path / "m.png").exists()


def test_view_refuses_bad_input(cli, tmp_path):
    (tmp_path / "bad.bgk").write_bytes(b"not a map")
    rc, _, err = run_cli(cli, "view", tmp_path / "bad.bgk", "-o", tmp_path / "x.html")
    assert rc != 0 and err.startswith("bgkmap: error: ") and "bad.bgk" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "x.html").exists()
    rc, _, err = run_cli(cli, "view", tmp_path / "missing.ot", "-o", tmp_path / "x.html")
    assert rc != 0 and "missing.ot" in err and len(err.strip().splitlines()) == 1
    rc, _, err = run_cli(cli, "view", tmp_path / "bad.bgk", "-o", tmp_path / "no" / "x.html")
    assert rc != 0 and "x.html" in err and len(err.strip().splitlines()) == 1


def test_planar_map_starts_from_above_with_grid_and_legend(cli, chromium, datasets, tmp_path):
    """Intel, --2d: seen from straight above, the whole map in the window, the grid's lines and the
    legend's colour ramp where the page says they are."""
    map_file = tmp_path / "intel.bgk"
    rc, _, err = run_cli(cli, "build", "-q", datasets / "carmen" / "intel-corrected.log.gz", "-o", map_file,
                         "--max-range", "20", "--2d")
    assert rc == 0, err
    page = tmp_path / "intel.html"
    rc, _, err = run_cli(cli, "view", "-q", map_file, "-o", page)
    assert rc == 0, err
    _, state = page_state(chromium, page, tmp_path)
    assert state["view"] == "top"
    # The map's box as the page projects it lies in its window (the --dump-dom run's viewport is
    # shorter than the screenshot's: the page fits the map to each).
    x0, y0, x1, y1 = numbers(state["map-screen"])
    width, height = (int(v) for v in state["viewport"].split("x"))
    assert 0 <= x0 < x1 <= width and 0 <= y0 < y1 <= height, (state["map-screen"], state["viewport"])
    assert y1 - y0 > 0.6 * height
    image = screenshot(chromium, page, tmp_path)
    assert image.shape[:2] == (700, 900)
    # In the screenshot: boxes in colour, spanning most of the height, none at the window's edges.
    saturation = image.max(axis=2) - image.min(axis=2)
    panel = np.zeros(image.shape[:2], bool)
    panel[:320, :360] = True
    coloured = (saturation > 60) & ~panel
    rows = np.nonzero(coloured.any(axis=1))[0]
    assert rows[-1] - rows[0] > 0.6 * 700
    edges = np.ones_like(coloured)
    edges[4:-4, 4:-4] = False
    assert not coloured[edges].any()
    # The grid: grey lines, brighter than the background (32, 36, 40), running across the window.
    grid = (image.sum(axis=2) > 32 + 36 + 40 + 45) & (saturation < 16) & ~panel
    assert (grid.sum(axis=0) > 300).sum() >= 3 and (grid.sum(axis=1) > 300).sum() >= 3
    # The legend's ramp: the lowest probability's violet at its left end, red at its right end.
    left, top, right, bottom = numbers(state["legend-box"])
    middle = (top + bottom) // 2
    assert np.abs(image[middle, left + 3] - [48, 18, 128]).max() <= 30, image[middle, left + 3]
    assert np.abs(image[middle, right - 4] - [230, 51, 26]).max() <= 30, image[middle, right - 4]


def test_height_clip_hides_the_cells_above_it(cli, chromium, datasets, tmp_path):
    """#clip=1.0 draws the occupied cells whose centres are at most 1 m high, counted here from the
    map file."""
    map_file = tmp_path / "structured.bgk"
    rc, _, err = run_cli(cli, "build", "-q", datasets / "sim_structured", "-o", map_file, "--ds", "0.1",
                         "--max-range", "8")
    assert rc == 0, err
    m = bgkmap.load(str(map_file))
    centres, _, _ = m.cells()
    occupied = m.state(centres) == bgkmap.OCCUPIED
    low = int(np.sum(occupied & (centres[:, 2] <= 1.0)))
    assert 1000 < low < int(np.sum(occupied))
    page = tmp_path / "map.html"
    rc, _, err = run_cli(cli, "view", "-q", map_file, "-o", page)
    assert rc == 0, err
    _, state = page_state(chromium, page, tmp_path, fragment="clip=1.0")
    assert state["view"] == "orbit"
    assert float(state["clip"]) == 1.0
    assert int(state["cells-drawn"]) == low
