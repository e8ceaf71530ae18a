"""Write tests/slowest_tests.txt (the order hint of tests/conftest.py) from a pytest junit XML: the tests of at least
`--min-s` seconds, slowest first. Times measured with tests running beside each other are inflated alike, so the
order still holds."""

from __future__ import annotations

import argparse
import xml.etree.ElementTree as ET
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "tests" / "slowest_tests.txt"
HEADER = """# Seconds and node id of the slowest lockstep tests (from {source}).
# tests/conftest.py sends these first, slowest first, when the tests run in parallel: an order hint only (a stale or
# missing line costs time, never a result). Refresh from a run's junit XML:
#     python scripts/slowest_tests.py test-artifacts/junit-lockstep.xml
"""


def node_id(case: ET.Element) -> str:
    """pytest's node id of a junit test case (`classname` is the dotted module path, then any class)."""
    dotted = case.get("classname", "").split(".")
    parts = list(dotted)
    while parts and not (ROOT / ("/".join(parts) + ".py")).exists():  # a test class: the last dotted parts
        parts.pop()
    return "::".join(["/".join(parts) + ".py", *dotted[len(parts):], case.get("name", "")])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("junit", type=Path)
    parser.add_argument("--min-s", type=float, default=5.0)
    args = parser.parse_args()
    cases = [(float(c.get("time", 0.0)), node_id(c)) for c in ET.parse(args.junit).getroot().iter("testcase")]
    rows = sorted((c for c in cases if c[0] >= args.min_s), reverse=True)
    OUT.write_text(HEADER.format(source=args.junit.name) + "".join(f"{t:.1f} {n}\n" for t, n in rows))
    print(f"{len(rows)} tests written to {OUT}")


if __name__ == "__main__":
    main()
