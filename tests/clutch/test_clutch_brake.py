"""The stick–slip shoe brake: the driven half held at rest, released at the brake's capacity, and the
regularised (tanh) brake converging to it as its velocity scale shrinks."""
import re
import numpy as np
import pytest

from rig.plants.clutch import FlatTappetClutch
from rig.plants.clutch.dynamics import ClutchDynamics
from rig.plants.clutch.loads import LinearMotor, LoadSum, ShoeBrake, constant
from rig.solvers import integrate

CLUTCH = dict(r0=0.055, r1=0.130, r2=0.005, k_a=3000.0, F_a1=1284.0, J1=0.4, J3=0.05)
MOTOR = (437.708, 3.870)
W0 = 100.0


def _overload(friction: str, omega_s: float = 0.5) -> ClutchDynamics:
    """Stand at speed, brake force raised from 1 kN to 19.75 kN (197.5 N·m) for 60 ms from 20 ms: the
    drum is stopped and held while the coupling ratchets, then released."""
    brake = ShoeBrake(0.01, 0.005, 1000.0, (0.02, 0.08), (19750.0, 1000.0), omega_s=omega_s, friction=friction)
    return ClutchDynamics(FlatTappetClutch(**CLUTCH), LinearMotor(*MOTOR), LoadSum([constant(2.0), brake]))


def _run(d: ClutchDynamics, t: np.ndarray, rtol: float = 1e-9):
    y0 = (d.equilibrium_angle(W0), 0.0, 0.0, W0, 1000.0)
    return integrate(d.problem(y0), (0.0, t[-1]), t_eval=t, rtol=rtol, atol=rtol * 1e-3)


@pytest.fixture(scope="module")
def held_run():
    d = _overload("stick_slip")
    t = np.linspace(0.0, 0.15, 3001)
    s = _run(d, t)
    return d, t, s, d.outputs(t, s.y)


def test_drum_is_held_at_rest_within_the_brake_capacity(held_run):
    d, t, s, out = held_run
    brakes = d.modes_at(t, brake=True)
    held = brakes == 0
    assert held.sum() > 100 and len(s.t_events["apex"]) >= 2         # held while the coupling ratchets
    assert np.all(s.y[3][held] == 0.0)                               # ω3 ≡ 0 and φ3 frozen in each spell
    assert np.all(np.diff(s.y[2])[held[:-1] & held[1:]] == 0.0)
    cap = 0.01 * s.y[4][held]
    need = out["M3"][held] - 2.0                                     # minus the constant idle load
    assert np.all(np.abs(need) <= cap * (1 + 1e-9))
    assert np.max(np.abs(need) / cap) > 0.9                          # the capacity is approached


def test_held_drum_is_released_at_the_capacity(held_run):
    """Hold → slip events happen where the needed torque reaches ±gain·F_b."""
    d, t, s, _ = held_run
    switches = [r for r in s.events if r.name == "brake_stick_slip"]
    assert len(switches) >= 2
    releases = [r for r in switches if d.modes_at(np.array([r.t + 1e-12]), brake=True)[0] != 0
                and d.modes_at(np.array([r.t - 1e-12]), brake=True)[0] == 0]
    assert releases
    for r in releases:
        need, cap = d._brake_need(r.t, r.y)
        assert abs(need) == pytest.approx(cap, rel=1e-6)


def test_tanh_brake_converges_to_the_stick_slip_brake():
    """The regularised brake's φr trajectory approaches the switched one roughly in proportion to ω_s."""
    t = np.linspace(0.0, 0.1, 1001)
    ref = _run(_overload("stick_slip"), t).y[0]
    errs = []
    for ws in (0.4, 0.1, 0.025):
        phi = _run(_overload("tanh", ws), t, rtol=1e-8).y[0]
        errs.append(np.max(np.abs(phi - ref)) / np.max(np.abs(ref)))
    assert errs[0] > errs[1] > errs[2]
    assert errs[2] < 0.2 * errs[0]


def test_only_one_stick_slip_brake():
    c = FlatTappetClutch(**CLUTCH)
    two = LoadSum([ShoeBrake(0.01, 0.005, 100.0, friction="stick_slip"),
                   ShoeBrake(0.01, 0.005, 100.0, friction="stick_slip")])
    with pytest.raises(ValueError, match="at most one stick-slip brake"):
        ClutchDynamics(c, LinearMotor(*MOTOR), two)
    with pytest.raises(ValueError, match="friction = 'dry'"):
        ShoeBrake(0.01, 0.005, 100.0, friction="dry")


@pytest.mark.parametrize("force, levels, said", [(-4000.0, (), "is -4000 N (force"),
                                                 (100.0, (-50.0,), "is -50 N from 0.2 s (force")])
def test_a_brake_command_that_pulls_is_refused(force, levels, said):
    """Shoes press: a negative force command once made the brake drive the shaft (to (a0 + 40)/b0 rad/s)."""
    from rig.plants.clutch.loads import ShoeBrake
    with pytest.raises(ValueError, match=rf"shoe brake: the force command {re.escape(said)}.*cannot drive the shaft"):
        ShoeBrake(0.01, 0.02, force, (0.2,) if levels else (), levels)
