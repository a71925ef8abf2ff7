#!/usr/bin/env python3
"""Where bgkmap's datasets are: $BGKMAP_DATASETS when set (and not empty), else the folder
../shared/datasets beside the checkout.

The C++ tests and benchmarks follow the same rule (datasets/locate.hpp), with CMake's
BGKMAP_DATASETS_DIR (default: the same ../shared/datasets) as the default.

Usage: datasets/locate.py                       prints the folder
       datasets/locate.py --require REL [--tag T] prints the path of REL inside it, or one line on
                                                 stderr naming what is missing (exit 1)
Importable: datasets_dir(), require(), Missing.
"""
import argparse
import os
import pathlib
import sys

ENV = "BGKMAP_DATASETS"
REPO = pathlib.Path(__file__).resolve().parents[1]
DEFAULT = REPO.parent / "shared" / "datasets"


class Missing(Exception):
    """A dataset (or the datasets folder) is not there; str() is the one-line message."""


def datasets_dir(build_default=None):
    """$BGKMAP_DATASETS, else build_default (a build's BGKMAP_DATASETS_DIR), else ../shared/datasets."""
    return pathlib.Path(os.environ.get(ENV) or build_default or DEFAULT)


def require(relative, tag="datasets", folder=None):
    """The path of `relative` inside the datasets folder; raises Missing naming it when absent."""
    folder = pathlib.Path(folder) if folder is not None else datasets_dir()
    if not folder.is_dir():
        raise Missing(f"{tag}: datasets folder {folder} not found (set {ENV}; datasets/README.md says what goes in it)")
    path = folder / relative
    if not path.exists():
        raise Missing(f"{tag}: {relative} is missing from {folder} (datasets/README.md says how to get it; "
                      f"{ENV} names another folder)")
    return path


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--require", metavar="REL", help="a file or folder inside the datasets folder")
    parser.add_argument("--tag", default="datasets", help="the caller's name, first on a missing line")
    args = parser.parse_args()
    if not args.require:
        print(datasets_dir())
        return 0
    try:
        print(require(args.require, args.tag))
    except Missing as missing:
        print(missing, file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
