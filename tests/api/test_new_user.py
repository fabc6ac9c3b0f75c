"""New-user surfaces of the Python API: channel classes exported and validated, sweeps that
refuse zero workers and write nothing with ``write=False``."""
from __future__ import annotations

import pytest

import kfcrit
from kfcrit.errors import InputError

SYSTEM = "name: scalar\nA: [[-1.25]]\nC: [[1]]\nQ: 1\nR: 2.5\n" \
         "channel: {model: bernoulli, arrival_probability: 0.5}\n"
SWEEP = "name: two points\nsystem: scalar.yaml\ngrid:\n  channel.arrival_probability: [0.3, 0.5]\n"


def test_channel_classes_are_public_and_validated():
    for name in ("Bernoulli", "GilbertElliott", "Trace", "LinkBudget", "Channel"):
        assert name in kfcrit.__all__ and getattr(kfcrit, name).__doc__
    assert kfcrit.Bernoulli("9/10").arrival_probability == kfcrit.Bernoulli(0.9).p
    with pytest.raises(InputError) as err:
        kfcrit.Bernoulli(90)
    assert err.value.field == "arrival_probability"
    with pytest.raises(InputError) as err:
        kfcrit.GilbertElliott(0, 0.5)
    assert err.value.field == "failure_rate"


def _files(tmp_path):
    (tmp_path / "scalar.yaml").write_text(SYSTEM)
    f = tmp_path / "sweep.yaml"
    f.write_text(SWEEP)
    return f


def test_sweep_refuses_zero_workers(tmp_path):
    f = _files(tmp_path)
    with pytest.raises(InputError) as err:
        kfcrit.sweep(f, tmp_path / "out", workers=0)
    assert err.value.field == "workers"
    assert not (tmp_path / "out").exists()


def test_sweep_without_write_writes_nothing(tmp_path):
    f = _files(tmp_path)
    before = sorted(p.name for p in tmp_path.iterdir())
    table = kfcrit.sweep(f, write=False)
    assert sorted(p.name for p in tmp_path.iterdir()) == before      # no folder, no journal
    # p_c = 1 − 1/a² = 9/25 = 0.36: 0.3 fails, 0.5 passes
    assert [r["decision"] for r in table.rows] == ["fail", "pass"]
