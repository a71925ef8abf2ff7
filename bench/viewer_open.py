#!/usr/bin/python3
"""Size and speed of `bgkmap view` pages: the time to write each, and to open it in headless
Chromium (the browser test's flags: software WebGL, SwiftShader).

Usage: bench/viewer_open.py [--bgkmap build/bgkmap] [--runs 3] [--max-cells N]
                            [--screenshots DIR] MAP...

For each map (.bgk, .ot, .bt): `bgkmap view MAP -o PAGE` --runs times (median wall seconds),
then Chromium --dump-dom on the page --runs times (median wall seconds of the whole browser run,
start to exit, and the page's own script time, `data-load-ms`: decoding, buffers, first frame),
and for scale the same browser run on an empty page. Debian's /usr/bin/python3 (python3-pil).
With --screenshots, a 900x700 screenshot of each page as DIR/<map name>.png (64 colours).
"""
import argparse
import os
import pathlib
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

from PIL import Image  # python3-pil

BROWSER_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--use-gl=swiftshader", "--enable-unsafe-swiftshader",
                 "--hide-scrollbars", "--window-size=900,700", "--virtual-time-budget=20000"]


def timed(command, **kwargs):
    t = time.monotonic()
    r = subprocess.run(command, capture_output=True, text=True, **kwargs)
    if r.returncode != 0:
        sys.exit(f"viewer_open: {' '.join(map(str, command))} failed: {r.stderr.strip()[-500:]}")
    return time.monotonic() - t, r


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("maps", nargs="+", type=pathlib.Path)
    parser.add_argument("--bgkmap", default="build/bgkmap")
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--max-cells", type=int)
    parser.add_argument("--screenshots", type=pathlib.Path)
    args = parser.parse_args()
    chromium = shutil.which("chromium") or sys.exit("viewer_open: chromium is not installed")

    print("| map | map size | occupied cells | boxes in the page | page size | write (median) | browser run (median) | page script (median) |")
    print("|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory(prefix="viewer_open.") as tmp:
        tmp = pathlib.Path(tmp)
        env = {**os.environ, "HOME": str(tmp)}
        empty = tmp / "empty.html"
        empty.write_text("<!DOCTYPE html><html><body></body></html>")
        empty_s = statistics.median(
            timed([chromium, *BROWSER_FLAGS, "--dump-dom", empty.as_uri()], cwd=tmp, env=env, timeout=600)[0]
            for _ in range(args.runs))
        print(f"| (an empty page) | | | | | | {empty_s:.1f} s | |", flush=True)
        for map_file in args.maps:
            page = tmp / (map_file.stem + ".html")
            view = [args.bgkmap, "view", map_file, "-o", page] + (["--max-cells", str(args.max_cells)] if args.max_cells else [])
            write_s = statistics.median(timed(view)[0] for _ in range(args.runs))
            open_s, script_ms = [], []
            for _ in range(args.runs):
                seconds, r = timed([chromium, *BROWSER_FLAGS, "--dump-dom", page.as_uri()], cwd=tmp, env=env, timeout=600)
                body = dict(re.findall(r'data-([a-z-]+)="([^"]*)"', re.search(r"<body([^>]*)>", r.stdout).group(1)))
                if "error" in body or body.get("ready") != "1":
                    sys.exit(f"viewer_open: {map_file}: the page did not load: {body}")
                open_s.append(seconds)
                script_ms.append(int(body["load-ms"]))
            print(f"| {map_file.name} | {map_file.stat().st_size / 1e6:.1f} MB | {int(body['map-occupied']):,} | "
                  f"{int(body['cells-held']):,} ({int(body['cells-drawn']):,} drawn) | {page.stat().st_size / 1e6:.1f} MB | "
                  f"{write_s:.2f} s | {statistics.median(open_s):.1f} s | {statistics.median(script_ms) / 1000:.2f} s |",
                  flush=True)
            if args.screenshots:
                args.screenshots.mkdir(parents=True, exist_ok=True)
                shot = tmp / "shot.png"
                timed([chromium, *BROWSER_FLAGS, "--screenshot=" + str(shot), page.as_uri()], cwd=tmp, env=env, timeout=600)
                Image.open(shot).convert("RGB").quantize(64).save(args.screenshots / (map_file.stem + ".png"), optimize=True)


if __name__ == "__main__":
    main()
