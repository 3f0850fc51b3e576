"""The host explains a NOK result: the device's FailMask decides, the host's re-evaluation of the received
curve says why (in display units), and a disagreement is an event, never silent."""
from types import SimpleNamespace

import numpy as np

from firmware_sim.digiforce import DigiForce
from rig.analysis.units import display_units
from rig.runner.reasons import NOT_REEVALUATED, ResultExplainer

ELEMENTS = [{"kind": "window", "name": "W", "x_min": "10 mm", "x_max": "20 mm", "y_min": "10 N", "y_max": "20 N",
             "entry": "left", "exit": "right"},
            {"kind": "window", "name": "off", "enabled": False, "x_min": "0 mm", "x_max": "1 mm", "y_min": "0 N",
             "y_max": "1 N"},
            {"kind": "threshold", "name": "S", "axis": "y", "value": "30 N", "direction": "rising"}]


def explainer():
    dev = DigiForce()
    config = {"elements": ELEMENTS}
    dev.set_program(1, config, units_required=True)
    return ResultExplainer(dev.get_program(1), display_units(dev.get_program(1), config))


def curve(y_peak):
    t = np.linspace(0, 0.1, 201)
    x = np.linspace(0.0, 0.03, t.size)
    return SimpleNamespace(t=t, x=x, y=np.full(t.size, 15.0) + (y_peak - 15.0) * (x > 0.025))


def result(mask, number=7):
    return SimpleNamespace(number=number, ok=mask == 0, fail_mask=mask)


def test_reasons_for_the_elements_the_device_failed_in_display_units():
    elements, mismatch = explainer().explain(result(0b10), curve(15.0))      # S never reaches 30 N: bit 1
    assert mismatch is None
    assert [(e["name"], e["kind"], e["ok"]) for e in elements] == [("W", "window", True), ("S", "threshold", False)]
    assert elements[0]["reason"] == ""
    assert elements[1]["reason"] == "the curve never crosses y = 30 N rising; closest y = 15 N at x = 0 mm"
    elements, mismatch = explainer().explain(result(0b00), curve(35.0))      # passes both: no reasons
    assert mismatch is None and all(e["ok"] and e["reason"] == "" for e in elements)


def test_a_disagreement_with_the_device_is_an_event_and_the_device_decides():
    elements, mismatch = explainer().explain(result(0b01), curve(35.0))      # the device failed W, the host passes it
    assert [e["ok"] for e in elements] == [False, True]
    assert elements[0]["reason"] == NOT_REEVALUATED["passes"]
    assert mismatch["number"] == 7 and mismatch["elements"] == ["W"]
    assert (mismatch["device_fail_mask"], mismatch["host_fail_mask"]) == (1, 0)
    elements, mismatch = explainer().explain(result(0b00), curve(15.0))      # the host fails S, the device does not
    assert [e["ok"] for e in elements] == [True, True] and mismatch["elements"] == ["S"]


def test_no_curve_or_more_elements_than_the_program_still_give_a_reason():
    elements, mismatch = explainer().explain(result(0b10), None)             # the curve did not arrive complete
    assert mismatch is None and elements[1]["reason"] == NOT_REEVALUATED["incomplete"]
    elements, mismatch = explainer().explain(result(0b100), curve(35.0))
    assert elements[2] == {"name": "element 2", "kind": "?", "ok": False, "reason": NOT_REEVALUATED["unknown"]}
    assert mismatch["elements"] == ["element 2"]
