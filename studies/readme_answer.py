"""Regenerates README.md's answer block (between ``<!-- answer:start -->`` and
``<!-- answer:end -->``) from a run folder of the main job.

    python studies/readme_answer.py runs/main            # print the block
    python studies/readme_answer.py runs/main --write    # and replace it in README.md

The block is ``explore._readme_answer.render`` of the run folder (tested in
``tests/test_explore.py``); the prose around it stays hand-written: re-read it when the block
changes.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from explore._readme_answer import render, replace_block

README = Path(__file__).resolve().parents[1] / "README.md"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", type=Path, help="a run folder of fingertip run / optimize")
    ap.add_argument("--write", action="store_true", help="replace the block in README.md")
    args = ap.parse_args()
    block = render(args.run)
    sys.stdout.write(block)
    if args.write:
        README.write_text(replace_block(README.read_text(), block))


if __name__ == "__main__":
    main()
