"""``python -m proofs_checks [--json]``: run every check, print a table, exit 1 on any failure."""
from __future__ import annotations

import json
import sys

from . import run_all


def format_table(rows: list[dict[str, object]]) -> str:
    """Plain-text table: step, source, method, result (details under failures)."""
    cols = ("step", "source", "method", "result")
    widths = {c: max(len(c), *(len(str(r[c])) for r in rows)) for c in cols}
    line = "  ".join(c.ljust(widths[c]) for c in cols)
    out = [line, "  ".join("-" * widths[c] for c in cols)]
    for r in rows:
        out.append("  ".join(str(r[c]).ljust(widths[c]) for c in cols).rstrip())
        if r["result"] != "pass":
            out.append(f"    -> {r['detail']}")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    rows = [o.to_dict() for o in run_all()]
    failed = sum(r["result"] != "pass" for r in rows)
    if "--json" in argv:
        print(json.dumps(rows, indent=2, ensure_ascii=False))
    else:
        print(format_table(rows))
        seconds = sum(float(r["seconds"]) for r in rows)
        print(f"\n{len(rows) - failed}/{len(rows)} checks passed in {seconds:.1f} s"
              + (f"; {failed} FAILED" if failed else ""))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
