"""One table and PNG from the cells of several ``floor_plan_table.py`` outputs (e.g. both guides).

Each item is ``LABEL=DIR:METHOD``: the cells of METHOD in DIR/families.json, shown as LABEL.
The outputs must hold the same arenas (the same ``--tests``); this is checked.

    python docs/scripts/merge_families.py --out DIR [--force] LABEL=DIR:METHOD [...]

Writes DIR/families.md, .csv, .png (as floor_plan_table.py) and DIR/families.json (the cells); an
earlier merge in DIR is replaced only with ``--force``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from floor_plan_table import tables

from nirl_mj.data.atomic import write_text


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True, type=Path)
    parser.add_argument("--force", action="store_true", help="replace an earlier merge in --out")
    parser.add_argument("items", nargs="+", help="LABEL=DIR:METHOD")
    args = parser.parse_args()
    if (args.out / "families.json").exists() and not args.force:
        parser.error(f"{args.out} already holds a merge (families.json); pass --force to replace it")
    cells, labels, arenas = [], [], set()
    for item in args.items:
        label, _, source = item.partition("=")
        directory, _, method = source.rpartition(":")
        store = Path(directory) / "families.json"
        if not (label and method and store.is_file()):
            parser.error(f"{item!r}: expected LABEL=DIR:METHOD with DIR/families.json present")
        done = json.loads(store.read_text())
        mine = [
            dict(c, method=label, guide=done.get("guide", "target"))
            for c in done["cells"]
            if c["method"] == method
        ]
        if not mine:
            parser.error(f"{item!r}: no cells of {method!r} in {store}")
        arenas |= {tuple(c["seeds"]) for c in mine}
        cells += mine
        labels.append(label)
    runs = {c["run"] for c in cells}
    if len(arenas) != len(runs):
        parser.error("the outputs were not run on the same arenas (different --tests)")
    args.out.mkdir(parents=True, exist_ok=True)
    write_text(args.out / "families.json", json.dumps({"cells": cells}, indent=1))
    tables(cells, labels, args.out)
    print(f"wrote {args.out}/families.md, .csv, .png, .json")


if __name__ == "__main__":
    main()
