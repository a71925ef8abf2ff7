"""bgkmap.tune: the parameters, the trials and the report `bgkmap tune` gives, in this process."""
import json

import pytest

import bgkmap
from conftest import run_cli

FLAGS = dict(max_range=8, ds=0.1, backend="cpu", threads=2, budget=3)


def test_tune_equals_the_cli(cli, scans, tmp_path):
    rc, _, err = run_cli(cli, "tune", "-q", *scans, "-o", tmp_path / "cli.yaml", "--report", tmp_path / "cli.json",
                         "--max-range", "8", "--ds", "0.1", "--backend", "cpu", "--threads", "2", "--budget", "3")
    assert rc == 0, err
    cli_report = json.loads((tmp_path / "cli.json").read_text())
    parameters, trials, report = bgkmap.tune(scans, output=str(tmp_path / "py.yaml"), **FLAGS)
    assert (tmp_path / "py.yaml").read_bytes() == (tmp_path / "cli.yaml").read_bytes()
    assert set(parameters) == {"ell", "prior_alpha", "prior_beta"}
    assert parameters == {p["name"]: p["chosen"] for p in cli_report["parameters"]}
    assert 1 <= len(trials) <= 3
    assert [t["values"] for t in trials] == [t["values"] for t in cli_report["trials"]]
    assert trials[0]["phase"] == "start" and trials[0]["values"]["ell"] == 0.2
    assert report["tuned"]["search"]["nll"] <= report["given"]["search"]["nll"] + 1e-12


def test_tune_errors(scans):
    with pytest.raises(ValueError, match="--holdout"):
        bgkmap.tune(scans, holdout=0.5, **FLAGS)
    with pytest.raises(ValueError, match="--method: nonesuch not in"):
        bgkmap.tune(scans, method="nonesuch", **FLAGS)
