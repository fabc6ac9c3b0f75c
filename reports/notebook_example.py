"""kfcrit from Python, as a notebook uses it (run: ``python reports/notebook_example.py``).

In Jupyter, evaluating ``record`` shows its verdict box and bounds table (``_repr_html_``);
``record.figure(name)`` returns matplotlib figures; ``kfcrit.sweep(...)`` returns a table with
``to_pandas()`` (pandas is the optional extra ``kfcrit[notebook]``).
"""
import tempfile
from pathlib import Path

import kfcrit

HERE = Path(__file__).resolve().parent

# 1. A system file: the 802.15.4 sensor link (mean-stable, but its link policy fails)
record = kfcrit.analyze(kfcrit.load_spec(HERE / "link-oqpsk-sensor.yaml"), quick=True)
print(record)                                  # <kfcrit Analysis ...: review fail>
print(record.decision, record.verdict)          # fail mean-stable
for reason in record.review.reasons:
    print(f"  {reason.status.value:>14}  {reason.check}: {reason.detail}")

# 2. A system built in Python: strings are exact, Python floats are binary floats
system = kfcrit.System([["5/4", 0], [1, "11/10"]], [[1, 1]], Q=20, R="5/2", name="general")
print(kfcrit.analyze(system, simulate=False).critical_value.expression)   # 9/25

# 3. Figures as matplotlib objects
names = record.figure_names()
fig = record.figure(names[0])                  # a matplotlib Figure: fig.savefig("phase.png")
print("figures:", ", ".join(names), "->", type(fig).__name__)

# 4. A sweep as a table (and a DataFrame when pandas is installed)
with tempfile.TemporaryDirectory() as results:   # the sweep's journal and outputs go here
    table = kfcrit.sweep(HERE / "sweep-link-distance.yaml", results, workers=1)
print(table)
try:
    frame = table.to_pandas()
    print(frame[["channel.distance_m", "channel.packet_bytes", "verdict", "decision"]].head())
except ImportError as exc:
    print(exc)
