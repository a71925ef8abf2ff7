"""The shell commands of README.md and docs/TUTORIAL.md run as written, in a temporary folder.

Each document's snippets (doc_snippets.py: ```bash/```sh blocks and the commands of tables) run in
order, in one folder per document, with `bgkmap` and `python3` on the PATH and `build`, `scripts`,
`examples` and `datasets` linked from the build and the checkout. Every output a snippet names
(`-o`, `--report`, `--json`, `--plot`) must exist afterwards. The README's table names small input
files (`scans/`, `lab.log`, ...): the test writes them first (scan_files.py). `../shared/datasets`
is replaced by the datasets folder (datasets/locate.py's rule); a snippet naming a dataset that is
missing is skipped, and fails under CI=true. Snippets must not depend on a skipped one.
"""
import json
import os
import pathlib
import re
import subprocess
import sys

import pytest

from conftest import locate, running_in_ci
import doc_snippets
import scan_files

SOURCE = pathlib.Path(os.environ.get("BGKMAP_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
DOCS = ["README.md", "docs/TUTORIAL.md"]
SHARED = "../shared/datasets"
OUTPUT = re.compile(r"(?:^|\s)(?:-o|--output|--report|--json|--plot|--slice)\s+(\S+)")


def datasets_folder():
    return locate.datasets_dir(os.environ.get("BGKMAP_DEFAULT_DATASETS_DIR"))


def workdir(tmp_path, cli):
    """A folder laid out as a checkout after the build: build/, scripts/, ... and bgkmap on the PATH."""
    build = pathlib.Path(os.environ.get("BGKMAP_BUILD_DIR") or pathlib.Path(cli).parent)
    (tmp_path / "build").symlink_to(build)
    for name in ("scripts", "examples", "datasets"):
        (tmp_path / name).symlink_to(SOURCE / name)
    bin_dir = tmp_path / ".bin"
    bin_dir.mkdir()
    (bin_dir / "bgkmap").symlink_to(cli)
    (bin_dir / "python3").symlink_to(sys.executable)  # the interpreter with numpy
    env = dict(os.environ, PATH=f"{bin_dir}{os.pathsep}{os.environ.get('PATH', '')}")
    return env


def write_table_inputs(folder):
    """The inputs the README's table of formats names, each a few scans of a box room."""
    scans = scan_files.room_scans()
    origins = [origin for origin, _ in scans]
    (folder / "scans").mkdir()
    (folder / "clouds").mkdir()
    for i, (origin, points) in enumerate(scans):
        scan_files.write_pcd(folder / "scans" / f"scan_{i}.pcd", origin, points)
        scan_files.write_ply(folder / "clouds" / f"cloud_{i}.ply", scan_files.in_sensor_frame(origin, points))
    scan_files.write_tum_poses(folder / "poses.txt", origins)
    scan_files.write_carmen_log(folder / "lab.log", origins)
    scan_files.write_kitti_sequence(folder / "kitti", scans)
    scan_files.write_scan_graph(folder / "scans.graph", [(o, scan_files.in_sensor_frame(o, p)) for o, p in scans])
    scan_files.write_octomap_log(folder / "scans.dat", scans)


def query_means(folder, env, bgk, points):
    """`bgkmap query --points` of the map: [(mean, state)] of each point's cell."""
    text = "".join("%g %g %g\n" % p for p in points)
    r = subprocess.run(["bgkmap", "query", bgk, "--points", "-"], cwd=folder, env=env, input=text,
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    return [(float(f[5]), f[7]) for f in (line.split() for line in r.stdout.splitlines())]


def assert_table_maps_show_the_room(folder, env):
    """The table's maps of one room, through five formats, have its walls where the room has
    them and agree with each other (KITTI's in the frame of its first scan)."""
    wall, centre = (4.95, 0.05, 1.05), (2.55, 0.05, 1.05)  # cells on the +x wall and inside
    first = scan_files.room_scans()[0][0]
    in_kitti = [tuple(a - b for a, b in zip(p, first)) for p in (wall, centre)]
    expected = query_means(folder, env, "scans.bgk", [wall, centre])
    assert expected[0][0] > 0.7 and expected[1][1] == "free", expected
    for bgk, points in [("clouds.bgk", [wall, centre]), ("graph.bgk", [wall, centre]),
                        ("dat.bgk", [wall, centre]), ("kitti.bgk", in_kitti)]:
        got = query_means(folder, env, bgk, points)
        assert [s for _, s in got] == [s for _, s in expected], (bgk, got, expected)
        assert got[0][0] == pytest.approx(expected[0][0], rel=1e-5), (bgk, got, expected)
    planar = query_means(folder, env, "lab.bgk", [wall, centre])
    assert planar[0][0] > 0.7 and planar[1][1] == "free", planar


def quoted_figures(text, pattern):
    """The groups of each match of pattern in text, thousands separators dropped."""
    return [tuple((g or "").replace(",", "") for g in m.groups()) for m in re.finditer(pattern, text)]


def assert_tutorial_counts_are_measured(folder, env, tutorial):
    """The map's counts and the answers to the points the tutorial quotes are those of its map."""
    info = json.loads(subprocess.run(["bgkmap", "info", "room.bgk", "--json"], cwd=folder, env=env,
                                     capture_output=True, text=True, check=True).stdout)
    counts = quoted_figures(tutorial, r"Of the ([\d,]+) cells with evidence, ([\d,]+) are occupied, ([\d,]+) free")
    assert counts == [(str(info["cells_with_evidence"]), str(info["occupied"]), str(info["free"]))], (counts, info)
    free, wall = query_means(folder, env, "room.bgk", [(2.5, 3.3, 1.0), (9.85, 3.3, 1.0)])
    assert free[1] == "free" and 5e-6 < free[0] < 2e-5 and wall[1] == "occupied", (free, wall)
    assert quoted_figures(tutorial, r"`occupied` \(mean (\d\.\d{3})\)") == [(f"{wall[0]:.3f}",)], wall


def assert_tutorial_scores_are_measured(folder, tutorial):
    """The scores and observed cell counts the tutorial quotes are those eval wrote."""
    bgkl = json.loads((folder / "room_eval.json").read_text())["protocols"]
    octomap = json.loads((folder / "both.json").read_text())["maps"][1]["protocols"]
    scores = [*quoted_figures(tutorial, r"AUC (\d\.\d{3})(?: and (\d\.\d{3}))?"),
              *quoted_figures(tutorial, r"NLL (\d\.\d{3})(?: and (\d\.\d{3}))?")]
    measured = [(bgkl["all_cells"]["auc"], bgkl["observed_cells"]["auc"]), (octomap["all_cells"]["auc"], None),
                (bgkl["all_cells"]["nll"], bgkl["observed_cells"]["nll"]), (octomap["all_cells"]["nll"], None)]
    assert scores == [tuple("" if v is None else f"{v:.3f}" for v in m) for m in measured], (scores, measured)
    observed = quoted_figures(tutorial, r"\(([\d,]+) against ([\d,]+)\)")
    assert observed == [tuple(str(p["observed_cells"]["n_positive"] + p["observed_cells"]["n_negative"])
                              for p in (octomap, bgkl))], observed


def missing_dataset(text, datasets):
    """The first dataset path the snippet names that is not there, else None."""
    for match in re.finditer(re.escape(SHARED) + r"/(\S+)", text):
        if not (datasets / match.group(1)).exists():
            return datasets / match.group(1)
    return None


def run_snippet(snippet, folder, env, datasets, where):
    """Runs one snippet; returns a skip reason (a dataset missing) or None; fails the test on error."""
    missing = missing_dataset(snippet.text, datasets)
    if missing:
        return f"{where}:{snippet.line} needs {missing}"
    text = snippet.text.replace(SHARED, str(datasets))
    r = subprocess.run(["bash", "-e", "-o", "pipefail", "-c", text], cwd=folder, env=env,
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, (f"{where}:{snippet.line} exited {r.returncode}:\n{snippet.text}\n"
                               f"--- stdout\n{r.stdout[-3000:]}\n--- stderr\n{r.stderr[-3000:]}")
    for output in OUTPUT.findall(text):
        path = folder / output
        written = any(path.iterdir()) if path.is_dir() else path.is_file() and path.stat().st_size > 0
        assert written, f"{where}:{snippet.line}: no {output} written:\n{snippet.text}"
    return None


@pytest.mark.parametrize("doc", DOCS)
def test_every_command_of_the_document_runs(doc, cli, tmp_path):
    env = workdir(tmp_path, cli)
    if doc == "README.md":
        write_table_inputs(tmp_path)
    datasets = datasets_folder()
    found = doc_snippets.snippets((SOURCE / doc).read_text(), doc)
    assert found, f"{doc} has no bash or sh snippets"
    skipped = [s for s in (run_snippet(s, tmp_path, env, datasets, doc) for s in found if not s.skip) if s]
    if doc == "README.md":
        assert_table_maps_show_the_room(tmp_path, env)
    else:
        assert_tutorial_counts_are_measured(tmp_path, env, (SOURCE / doc).read_text())
        assert_tutorial_scores_are_measured(tmp_path, (SOURCE / doc).read_text())
    if skipped:
        message = f"{doc}: {len(skipped)} snippets skipped: " + "; ".join(skipped)
        if running_in_ci():
            pytest.fail(message)
        pytest.skip(message)


def test_the_readme_skips_only_what_a_test_cannot_run():
    marked = [s for s in doc_snippets.snippets((SOURCE / "README.md").read_text()) if s.skip]
    assert [s.text.split()[0] for s in marked] == ["bash", "bash", "bgkmap", "pip"], marked
    assert not [s for s in doc_snippets.snippets((SOURCE / "docs/TUTORIAL.md").read_text()) if s.skip]


def test_the_readme_is_a_short_guide():
    readme = (SOURCE / "README.md").read_text()
    headings = [line for line in readme.splitlines() if line.startswith("## ")]
    assert headings == ["## Install (Debian 12)", "## Quick start", "## Map your own data", "## Outputs",
                        "## Methods", "## Python", "## More"], headings
    assert len(readme.splitlines()) <= 150


def test_ci_runs_the_readmes_test_command():
    readme = [s.text for s in doc_snippets.snippets((SOURCE / "README.md").read_text()) if "ctest" in s.text]
    ci = [line for line in (SOURCE / ".ci" / "run").read_text().splitlines() if "ctest" in line]
    assert len(readme) == 1 and ci == readme, (readme, ci)


def test_snippets_are_the_shell_blocks_and_the_table_commands():
    markdown = "\n".join([
        "text", "```bash", "echo one", "echo two", "```", "```python", "print(3)", "```",
        "<!-- docs-test: skip: needs root -->", "```sh", "sudo true", "```",
        "| data | command |", "|---|---|", "| a | `bgkmap build a -o a.bgk` |",
        "| b | `bgkmap build b -o b.bgk` <!-- docs-test: skip: no bag --> |",
        "| c | `x | y` |", "", "| not | commands |", "|---|---|", "| d | `ls` |"])
    got = [(s.line, s.text, s.skip) for s in doc_snippets.snippets(markdown)]
    assert got == [(3, "echo one\necho two", ""), (11, "sudo true", "needs root"),
                   (15, "bgkmap build a -o a.bgk", ""), (16, "bgkmap build b -o b.bgk", "no bag"),
                   (17, "x | y", "")]


@pytest.mark.parametrize("markdown, error", [
    ("<!-- docs-test: skip -->\n```bash\ntrue\n```", "is not 'skip: REASON'"),
    ("<!-- docs-test: skip: why -->\ntext\n```bash\ntrue\n```", "not followed by a bash or sh block"),
    ("```bash\ntrue\n", "never closed"),
])
def test_a_bad_marker_or_block_is_refused(markdown, error):
    with pytest.raises(ValueError, match=error):
        doc_snippets.snippets(markdown)


@pytest.mark.parametrize("text, error", [("false", "exited 1"), ("echo -o made.bgk", "no made.bgk written")])
def test_a_failing_snippet_or_a_missing_output_fails(text, error, tmp_path):
    with pytest.raises(AssertionError, match=error):
        run_snippet(doc_snippets.Snippet(1, text), tmp_path, dict(os.environ), tmp_path, "doc")


def test_a_snippet_naming_a_missing_dataset_is_skipped(tmp_path):
    snippet = doc_snippets.Snippet(4, f"bgkmap build {SHARED}/none.log -o n.bgk")
    assert run_snippet(snippet, tmp_path, dict(os.environ), tmp_path, "doc") == f"doc:4 needs {tmp_path / 'none.log'}"


def heading_anchors(markdown):
    """GitHub's anchors of a document's headings: lower case, punctuation dropped, spaces as dashes."""
    return {re.sub(r"[^\w\- ]", "", line.lstrip("#").strip().lower()).replace(" ", "-")
            for line in markdown.splitlines() if line.startswith("#")}


def test_every_link_of_the_docs_finds_its_file_and_heading():
    docs = [SOURCE / "README.md", SOURCE / "datasets" / "README.md", *sorted((SOURCE / "docs").rglob("*.md"))]
    broken = []
    for doc in docs:
        for target in re.findall(r"\]\(([^)\s]+)\)", doc.read_text()):
            if re.match(r"[a-z]+:", target):
                continue  # a web address
            path, _, anchor = target.partition("#")
            linked = (doc.parent / path) if path else doc
            if not linked.exists():
                broken.append(f"{doc.relative_to(SOURCE)}: {target} (no such file)")
            elif anchor and linked.suffix == ".md" and anchor not in heading_anchors(linked.read_text()):
                broken.append(f"{doc.relative_to(SOURCE)}: {target} (no such heading)")
    assert not broken, broken
