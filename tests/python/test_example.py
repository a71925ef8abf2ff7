"""The example in examples/ runs on sim_structured and writes what it says."""
import os
import subprocess
import sys


def test_quickstart_example_runs(source_dir, datasets, tmp_path):
    r = subprocess.run([sys.executable, str(source_dir / "examples" / "python_quickstart.py"),
                        str(datasets / "sim_structured"), str(tmp_path)],
                       capture_output=True, text=True, env=dict(os.environ))
    assert r.returncode == 0, r.stderr
    assert "12 scans on" in r.stdout and "AUC hits vs. halfway points: " in r.stdout
    auc = float(r.stdout.split("AUC hits vs. halfway points: ")[1].split()[0])
    assert auc > 0.9
    for name in ("map.bgk", "map.ot", "octomap.ot"):
        assert (tmp_path / name).stat().st_size > 0
