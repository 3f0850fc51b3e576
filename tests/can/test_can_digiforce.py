"""The CAN node in front of the real DigiForce unit: host commands drive a measurement, the curve
and result the unit produced arrive at the host intact (to the wire quantisation)."""
from __future__ import annotations

import can
import numpy as np
import pytest

from drivers.can import CanHost
from firmware_sim.can_node import CanNode, X_LSB, Y_LSB
from firmware_sim.digiforce import DigiForce


def test_measurement_commanded_over_can():
    dev_bus = can.Bus(interface="virtual", channel="can-df", preserve_timestamps=True)
    host_bus = can.Bus(interface="virtual", channel="can-df", preserve_timestamps=True)
    try:
        unit = DigiForce()
        node = CanNode(dev_bus, unit, bitrate=1_000_000)
        host = CanHost(host_bus)
        host.start()
        node.advance_to(0.0)                                   # start at device time 0
        t = np.arange(4000) * 1e-4
        x, y = 2.0 * np.sin(np.pi * t / 0.8) ** 2, 1e-3 * np.sin(np.pi * t / 0.8)
        unit.feed(t[:2000], x[:2000], y[:2000])
        host.stop()
        node.advance_to(0.2)                                   # stop requested at 0.2 s
        unit.feed(t[2000:], x[2000:], y[2000:])                # ... takes effect on the next samples
        result = unit.last_result
        assert result is not None and result.curve.x.size > 1000
        for k in range(1, 40):
            node.advance_to(0.2 + 0.05 * k)
            host.poll()
        (curve,) = host.curves()
        np.testing.assert_array_equal(curve.x, np.rint(result.curve.x / X_LSB) * X_LSB)
        np.testing.assert_array_equal(curve.y, np.rint(result.curve.y / Y_LSB) * Y_LSB)
        np.testing.assert_allclose(curve.t, result.curve.t, rtol=0, atol=5e-6)
        got = host.results[result.number]
        assert got.ok == result.ok
        for key, value in got.process_values.items():
            assert value == pytest.approx(result.process_values[key], rel=1e-6, abs=1e-9)
        assert set(got.process_values) == {"x_max", "x_min", "y_max", "y_min", "x_at_y_max", "y_at_x_max",
                                           "x_end", "y_end", "duration"}
        assert [a["status"] for a in host.acks] == ["done", "done"]
        assert host.status["last_ok"] == result.ok and host.events == []
    finally:
        dev_bus.shutdown()
        host_bus.shutdown()
