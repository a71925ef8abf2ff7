"""bgkmap.build (every --method, the CLI's report) and the metrics on arrays."""
import json
import math

import numpy as np
import pytest

import bgkmap
from conftest import FLAGS, SETTINGS, run_cli


def test_build_report_equals_the_cli_report(cli, scans, tmp_path):
    flags = ["--max-range", "8", "--ds", "0.1", "--backend", "cpu", "--method", "counting"]
    rc, _, err = run_cli(cli, "build", "-q", *scans, "-o", tmp_path / "cli.bgk", "--report", tmp_path / "r.json", *flags)
    assert rc == 0, err
    cli_report = json.loads((tmp_path / "r.json").read_text())
    report = bgkmap.build(scans, method="counting", outputs=[str(tmp_path / "py.bgk")], max_range=8, ds=0.1,
                          backend="cpu")
    assert report["counts"] == cli_report["counts"]
    assert report["params"] == cli_report["params"]
    assert report["inputs"] == cli_report["inputs"]
    assert set(report["timing"]) == set(cli_report["timing"])
    assert (tmp_path / "py.bgk").read_bytes() == (tmp_path / "cli.bgk").read_bytes()


@pytest.mark.parametrize("method", bgkmap.METHODS)
def test_every_method_builds(method, scans, tmp_path):
    out = tmp_path / "m.ot"
    # Its own parameters as keywords at their defaults (free_resolution coarser): the report holds each.
    own = {**bgkmap.METHOD_PARAMS[method], "free_resolution": 0.2}
    report = bgkmap.build(scans[:2], method=method, outputs=[str(out)], max_range=8, ds=0.2, backend="cpu", **own)
    assert report["params"]["method"] == method
    for keyword, value in bgkmap.METHOD_PARAMS[method].items():
        assert report["params"][keyword] == own[keyword], keyword
        assert type(report["params"][keyword]) is type(value), keyword
    assert report["counts"]["scans"] == 2
    assert report["counts"]["cells_with_evidence"] > 1000
    assert out.read_bytes().startswith(b"# Octomap OcTree file")


def test_methods_are_the_cli_methods(cli):
    rc, out, err = run_cli(cli, "build", "--help")
    assert rc == 0, err
    assert len(bgkmap.METHODS) >= 6
    for method in bgkmap.METHODS:
        assert method in out


def test_octomap_reproduces_the_reference_cell_count(datasets):
    # datasets/README.md: the OctoMap of all 12 scans at 0.1 m, max range 8, has 197,291 known cells.
    report = bgkmap.build(str(datasets / "sim_structured"), method="octomap", max_range=8)
    assert report["counts"]["cells_with_evidence"] == 197291


def test_build_errors(tmp_path, scans):
    with pytest.raises(ValueError, match="bgkl"):
        bgkmap.build(scans, method="nope")
    with pytest.raises(ValueError, match="--output: .*m.png: unknown map format"):  # a bad name: a usage error
        bgkmap.build(scans, outputs=[str(tmp_path / "m.png")])
    with pytest.raises(TypeError, match="unknown keyword 'prob_hitt'"):  # as Mapper's unknown parameter
        bgkmap.build(scans, method="octomap", prob_hitt=0.7)
    # Out of range: named by the keyword, as Python spells it (the command line says --prob-hit).
    with pytest.raises(ValueError, match=r"^prob_hit must be in \(0.5, 1\)$"):
        bgkmap.build(scans, method="octomap", prob_hit=0.2)
    with pytest.raises(ValueError, match=r"^block_depth must be a whole number in \[1, 7\]$"):
        bgkmap.build(scans, block_depth=9)


def test_resume_continues_a_map(scans, tmp_path):
    first = tmp_path / "first.bgk"
    bgkmap.build(scans[:2], outputs=[str(first)], max_range=8, backend="cpu")
    bgkmap.build(scans[2:], outputs=[str(tmp_path / "resumed.bgk")], resume=str(first), backend="cpu")
    bgkmap.build(scans, outputs=[str(tmp_path / "whole.bgk")], max_range=8, backend="cpu")
    assert (tmp_path / "resumed.bgk").read_bytes() == (tmp_path / "whole.bgk").read_bytes()
    with pytest.raises(ValueError, match="cannot change 'ell' when resuming"):
        bgkmap.build(scans[2:], resume=str(first), ell=0.3)


def test_config_and_keywords_are_the_clis_config_and_flags(cli, scans, tmp_path):
    """Defaults, then the config file, then the keywords: as the command's --config and flags."""
    config = tmp_path / "p.yaml"
    config.write_text("resolution: 0.2\nell: 0.4\nds: 0.2\nfree_resolution: 0.3\nthreads: 1\n")
    flags = ["--method", "bgk", "--config", config, "--free-resolution", "0.25", "--max-range", "8", "--backend", "cpu"]
    rc, _, err = run_cli(cli, "build", "-q", *scans[:2], "-o", tmp_path / "cli.bgk", "--report", tmp_path / "r.json", *flags)
    assert rc == 0, err
    cli_report = json.loads((tmp_path / "r.json").read_text())
    report = bgkmap.build(scans[:2], method="bgk", outputs=tmp_path / "py.bgk", config=config, free_resolution=0.25,
                          max_range=8, backend="cpu")
    assert report["params"] == cli_report["params"]
    assert (report["params"]["resolution"], report["params"]["free_resolution"], report["params"]["threads"]) == (0.2, 0.25, 1)
    assert (tmp_path / "py.bgk").read_bytes() == (tmp_path / "cli.bgk").read_bytes()
    first = tmp_path / "first.bgk"
    bgkmap.build(scans[:1], outputs=first, max_range=8, backend="cpu")
    # The config's values go over the stored map's: its first key that differs is refused.
    with pytest.raises(ValueError, match=r"^cannot change 'ds' when resuming a map \(stored 0.0, asked 0.2\)$"):
        bgkmap.build(scans[1:2], resume=first, config=config)


def test_skipped_inputs_and_keyword_errors(cli, scans, tmp_path):
    bad = tmp_path / "bad.pcd"
    bad.write_text("not a pcd file\n")
    inputs = [scans[0], str(bad), scans[1]]
    rc, _, err = run_cli(cli, "build", "-q", *inputs, "-o", tmp_path / "cli.ot", "--report", tmp_path / "r.json",
                         "--skip-bad-inputs", *FLAGS)
    assert rc == 0, err
    cli_report = json.loads((tmp_path / "r.json").read_text())
    report = bgkmap.build(inputs, outputs=tmp_path / "py.ot", skip_bad_inputs=True, **SETTINGS)
    assert report["counts"]["scans"] == 2 and report["counts"]["inputs_skipped"] == 1
    assert report["skipped_inputs"] == cli_report["skipped_inputs"] and report["skipped_inputs"][0]["path"] == str(bad)
    assert (tmp_path / "py.ot").read_bytes() == (tmp_path / "cli.ot").read_bytes()
    with pytest.raises(bgkmap.InputError, match="bad.pcd"):  # without skip_bad_inputs the bad file stops the build
        bgkmap.build(inputs, outputs=tmp_path / "stopped.ot", **SETTINGS)
    assert not (tmp_path / "stopped.ot").exists()
    with pytest.raises(ValueError, match="--gp-covariance: cosine not in"):
        bgkmap.build(scans, method="gpom", gp_covariance="cosine")
    with pytest.raises(ValueError, match="--checkpoint: .*native .bgk"):
        bgkmap.build(scans, checkpoint=tmp_path / "c.ot", checkpoint_every=2)
    with pytest.raises(ValueError, match="--config: File does not exist"):
        bgkmap.build(scans, config=tmp_path / "absent.yaml")


def reference_auc(labels, scores):
    """Mann-Whitney with ties counted half: the plain definition."""
    pos, neg = scores[labels == 1], scores[labels == 0]
    greater = (pos[:, None] > neg[None, :]).sum() + 0.5 * (pos[:, None] == neg[None, :]).sum()
    return greater / (len(pos) * len(neg))


def test_metrics_on_arrays():
    rng = np.random.default_rng(3)
    labels = rng.integers(0, 2, 500)
    scores = np.round(np.clip(labels * 0.3 + rng.random(500) * 0.7, 0, 1), 2)  # rounded: many ties
    assert bgkmap.auc(labels, scores) == pytest.approx(reference_auc(labels, scores), abs=1e-12)
    assert bgkmap.auc(labels.astype(bool), scores) == bgkmap.auc(labels, scores)
    p = np.clip(scores, 1e-6, 1 - 1e-6)
    nll = -np.mean(np.where(labels == 1, np.log(p), np.log(1 - p)))
    assert bgkmap.nll(labels, scores) == pytest.approx(nll, rel=1e-12)
    m = bgkmap.metrics(labels, scores, occupied_threshold=0.5)
    predicted = scores > 0.5
    assert m["accuracy"] == pytest.approx(np.mean(predicted == (labels == 1)), abs=1e-12)
    assert m["precision"] == pytest.approx(np.sum(predicted & (labels == 1)) / np.sum(predicted), abs=1e-12)
    assert m["n_positive"] == labels.sum() and m["auc"] == bgkmap.auc(labels, scores)
    assert m["average_precision"] == bgkmap.average_precision(labels, scores)
    c = bgkmap.curves(labels, scores)
    assert c["fpr"][0] == 0 and c["tpr"][0] == 0 and c["fpr"][-1] == 1 and c["tpr"][-1] == 1
    assert np.trapz(c["tpr"], c["fpr"]) == pytest.approx(m["auc"], abs=1e-12)
    assert bgkmap.auc(np.ones(3, int), np.full(3, 0.5)) != bgkmap.auc(np.ones(3, int), np.full(3, 0.5))  # NaN
    assert bgkmap.auc(np.array([0, 1]), np.array([0.5, 0.5])) == 0.5


def test_metric_inputs_are_checked():
    with pytest.raises(ValueError, match="differ in length"):
        bgkmap.auc(np.array([0, 1]), np.array([0.1]))
    with pytest.raises(ValueError, match=r"labels\[1\] is 2, not 0 or 1"):
        bgkmap.auc(np.array([0, 2]), np.array([0.1, 0.2]))
    with pytest.raises(ValueError, match=r"scores\[0\] is NaN"):
        bgkmap.auc(np.array([0, 1]), np.array([math.nan, 0.2]))
    with pytest.raises(TypeError, match="labels must be bool or integer"):
        bgkmap.auc(np.array([0.0, 1.0]), np.array([0.1, 0.2]))


def test_forgetting_keyword_is_the_flag_and_a_loaded_map_saves_as_stored(cli, scans, tmp_path):
    flags = ["--max-range", "8", "--ds", "0.1", "--backend", "cpu", "--forget-half-life", "3"]
    rc, _, err = run_cli(cli, "build", "-q", *scans, "-o", tmp_path / "cli.bgk", *flags)
    assert rc == 0, err
    bgkmap.build(scans, outputs=[str(tmp_path / "py.bgk")], max_range=8, ds=0.1, backend="cpu", forget_half_life=3)
    assert (tmp_path / "py.bgk").read_bytes() == (tmp_path / "cli.bgk").read_bytes()
    # load() keeps each block's time (a Mapper may go on); save() writes the same file again.
    bgkmap.load(str(tmp_path / "py.bgk")).save(str(tmp_path / "again.bgk"))
    assert (tmp_path / "again.bgk").read_bytes() == (tmp_path / "py.bgk").read_bytes()
    with pytest.raises(ValueError, match="forget_half_life must be in"):
        bgkmap.build(scans, outputs=[str(tmp_path / "x.bgk")], forget_half_life=-1)
