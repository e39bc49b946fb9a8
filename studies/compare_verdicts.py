"""Two reports' verdicts side by side: which changed, and which contradict each other (one reproduces where the
other does not). For the same pipeline run twice, with other seeds or on another machine.

    python studies/compare_verdicts.py A/summary.json B/summary.json [--names "seeds 0-9" "seeds 10-19"]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

OPPOSITE = {("reproduces", "does not reproduce"), ("does not reproduce", "reproduces")}


def verdicts(path: Path) -> dict[tuple[str, str], str]:
    summary = json.loads(path.read_text())
    return {
        (name, claim): verdict for name, section in summary.items() for claim, verdict in section["verdicts"].items()
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("first", type=Path)
    parser.add_argument("second", type=Path)
    parser.add_argument("--names", nargs=2, default=["first", "second"])
    args = parser.parse_args()
    a, b = verdicts(args.first), verdicts(args.second)
    shared = [key for key in a if key in b]
    changed = [key for key in shared if a[key] != b[key]]
    opposite = [key for key in changed if (a[key], b[key]) in OPPOSITE]
    print(f"| experiment | claim | {args.names[0]} | {args.names[1]} |\n|---|---|---|---|")
    for key in shared:
        mark = " (opposite)" if key in opposite else " (changed)" if key in changed else ""
        print(f"| {key[0]} | {key[1]} | {a[key]} | {b[key]}{mark} |")
    print(f"\n{len(shared)} claims in both: {len(changed)} changed, {len(opposite)} to the opposite verdict")


if __name__ == "__main__":
    main()
