"""End to end: with an accuracy requirement, the link design reads the binding requirement."""
from __future__ import annotations

import yaml

from kfcrit.analysis.record import analyze_system
from kfcrit.analysis.spec import spec_from_mapping

from ..conftest import REPORTS


def test_link_design_uses_the_accuracy_requirement_p_v():
    doc = yaml.safe_load((REPORTS / "link-cc2420-retries.yaml").read_text())
    doc["channel"]["distance_m"] = 80
    doc["requirements"] = {"max_mean_error_trace": 100}
    rec = analyze_system(spec_from_mapping(doc), simulate=False).to_dict()
    p_s, p_v = rec["design"]["required_arrival_probability"]["interval"]
    lb = rec["link_budget"]
    assert p_s < p_v and lb["required_arrival_probability"]["design_value"] == p_v
    assert lb["max_distance_m"] == rec["design"]["radio"]["max_distance_m"]["sufficient"]["value"]
    # the stability requirement alone (p_c = 9/25) would allow a longer link
    assert p_v > 9 / 25
