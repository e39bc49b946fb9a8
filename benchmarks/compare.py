"""Which recorded numbers got worse: two versions of benchmarks/measured.json, number by number.

    python benchmarks/compare.py OLD.json NEW.json [--tolerance 0.1]
    git show REV:benchmarks/measured.json > /tmp/old.json && python benchmarks/compare.py /tmp/old.json \
        benchmarks/measured.json

Every number both files hold under the same record and name is compared in the way it improves (its record's
``better``): a rate that fell, or a time, a memory or a cost ratio that rose, by more than ``--tolerance`` of the
old number (0.1: 10%) is a regression. Prints one line per regression (with both machines where the two runs
were on different ones: such a comparison means little) and exits 1 when there is any, else 0. A record without
numbers (one written before the records held them) is left out and named; malformed numbers are one ``error:`` line.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from common import HIGHER, LOWER


def numbers(name: str, entry: dict) -> dict[str, tuple[float | None, str, str]]:
    """A record's numbers by name: each value (None where the run measured none), its unit and the way it
    improves; none for a record without numbers; a ValueError saying what is wrong where they are malformed."""
    if not isinstance(entry, dict):
        raise ValueError(f"record {name!r} is not a JSON object")
    if "value" not in entry and "values" not in entry:
        return {}
    if "value" in entry and "values" in entry:
        raise ValueError(f"record {name!r} holds both one value and named values")
    values = {"value": entry["value"]} if "value" in entry else entry["values"]
    if not isinstance(values, dict) or not values:
        raise ValueError(f"record {name!r}: values must be named numbers")

    def each(field: str) -> dict:
        given = entry.get(field)
        per = given if isinstance(given, dict) else dict.fromkeys(values, given)
        if set(per) != set(values) or not all(isinstance(v, str) for v in per.values()):
            raise ValueError(f"record {name!r}: {field} must be one text or one per value")
        return per

    units, senses = each("unit"), each("better")
    found = {}
    for key, value in values.items():
        if value is not None and (isinstance(value, bool) or not isinstance(value, int | float)):
            raise ValueError(f"record {name!r}: {key} is {value!r}, not a number")
        if senses[key] not in (HIGHER, LOWER):
            raise ValueError(f"record {name!r}: better of {key} is {senses[key]!r}, not {HIGHER} or {LOWER}")
        found[key] = (None if value is None or not math.isfinite(value) else float(value), units[key], senses[key])
    return found


def worse_by(old: float, new: float, better: str) -> float:
    """How much worse ``new`` is than ``old`` as a share of ``old`` (0 where it is as good or better)."""
    change = (old - new) if better == HIGHER else (new - old)
    if change <= 0:
        return 0.0
    return math.inf if old == 0 else change / abs(old)


def regressions(old: dict, new: dict, tolerance: float) -> tuple[list[str], int, list[str]]:
    """The lines of every number of ``new`` worse than the same number of ``old`` by more than ``tolerance``, how
    many numbers were compared, and the records both files hold that one holds without numbers."""
    lines, compared, textual = [], 0, []
    for name in sorted(set(old) & set(new)):
        before, after = numbers(name, old[name]), numbers(name, new[name])
        if not before or not after:
            textual.append(name)
            continue
        machines = (old[name].get("machine"), new[name].get("machine"))
        where = "" if machines[0] == machines[1] else f" (on {machines[0]}, then on {machines[1]})"
        for key in sorted(set(before) & set(after), key=list(after).index):
            (was, unit, better), (now, _, _) = before[key], after[key]
            if was is None or now is None:
                continue
            compared += 1
            if (share := worse_by(was, now, better)) > tolerance:
                label = name if key == "value" else f"{name} {key}"
                lines.append(f"{label}: {was:g} -> {now:g} {unit} ({share:.0%} worse){where}")
    return lines, compared, textual


def read(path: Path) -> dict:
    try:
        loaded = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise SystemExit(f"error: {path}: {getattr(exc, 'strerror', None) or exc}") from None
    if not isinstance(loaded, dict):
        raise SystemExit(f"error: {path}: not a JSON object of named records")
    return loaded


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("old", type=Path)
    parser.add_argument("new", type=Path)
    parser.add_argument("--tolerance", type=float, default=0.1, help="the share worse that is a regression")
    args = parser.parse_args(argv)
    if not (math.isfinite(args.tolerance) and args.tolerance >= 0):
        raise SystemExit("error: --tolerance must be a share of at least 0")
    old, new = read(args.old), read(args.new)
    try:
        lines, compared, textual = regressions(old, new, args.tolerance)
    except ValueError as exc:
        raise SystemExit(f"error: {exc}") from None
    if textual:
        print(f"left out, without numbers in one of the files: {', '.join(textual)}")
    print(f"{compared} numbers compared, {len(lines)} worse by more than {args.tolerance:.0%}")
    for line in lines:
        print(f"  {line}")
    return 1 if lines else 0


if __name__ == "__main__":
    sys.exit(main())
