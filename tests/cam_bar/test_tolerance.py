"""Tolerance analysis of the cam-bar chain (MODELS §3.5): sensitivities, linear sums, Monte Carlo, four-bar."""
from __future__ import annotations

from math import log
from pathlib import Path

import numpy as np
import pytest

from rig.plants.cam_bar import PinInsertionMechanism, SingularPositionError
from rig.plants.cam_bar.fourbar import (EXAMPLE_LENGTHS, EXAMPLE_TOLERANCES, influence_factors,
                                        rocker_angle)
from rig.plants.cam_bar.montecarlo import (PROBE, buildable_probe, monte_carlo, sample_clearance,
                                           sample_deviations, tasks)
from rig.plants.cam_bar.tolerance import (PARAMS, CamChain, ToleranceSet, linear_analysis,
                                          load_tolerances)
from rig.scene import SceneError

PHI = np.radians(np.arange(0.0, 360.0, 3.0))
THESIS = {"x_A0": 21e-6, "y_A0": 21e-6, "l3": 54e-6, "r": 50e-6, "s0": 68.386e-6, "L3": 94e-6, "l4": 76e-6,
          "e_sk": 93.718e-6}


@pytest.fixture(scope="module")
def chain() -> CamChain:
    return CamChain.from_mechanism(PinInsertionMechanism(), PHI)


def test_data_file_holds_the_thesis_tolerances():
    tol = load_tolerances()
    assert dict(tol.T) == pytest.approx(THESIS, rel=1e-12)
    assert tol.clearance_lambda == pytest.approx(log(20) / 0.05e-3, rel=2e-3)


def test_undeviated_chain_reproduces_the_programmed_stroke(chain):
    mech = PinInsertionMechanism()
    assert chain.deviation({})[0] == pytest.approx(np.zeros(PHI.size), abs=1e-12)
    assert chain.stroke({})[0] == pytest.approx(mech.program.evaluate(PHI).s, abs=1e-12)


@pytest.mark.parametrize("name", PARAMS)
def test_every_sensitivity_matches_central_differences_of_the_full_chain(chain, name):
    h = 1e-7
    fd = (chain.stroke({name: h}) - chain.stroke({name: -h}))[0] / (2 * h)
    sens = chain.sensitivities()[name]
    scale = max(np.max(np.abs(sens)), 1e-3)
    assert np.max(np.abs(sens - fd)) < 1e-6 * scale + 1e-8
    assert np.max(np.abs(sens)) > 1e-3  # every parameter matters somewhere


def test_bar_side_sensitivities_are_exact_for_trivial_parameters(chain):
    sens = chain.sensitivities()
    # moving the slider origin s0 shifts the stroke 1:1 (x_D is fixed by ψ): ∂s/∂s0 = 1 exactly
    assert sens["s0"] == pytest.approx(np.ones(PHI.size), abs=1e-12)
    # the lever ratio: the cam pitch radius is amplified about 4× at the gripper (MODELS §3)
    assert 3.5 < np.max(np.abs(sens["r"])) < 4.5


def test_linear_sums_follow_their_definitions(chain):
    lin = linear_analysis(chain, ToleranceSet(THESIS))
    c = np.stack([lin.sensitivity[k] * THESIS[k] for k in PARAMS])
    assert lin.signed == pytest.approx(c.sum(axis=0), abs=1e-15)
    assert lin.worst == pytest.approx(np.abs(c).sum(axis=0), abs=1e-15)
    assert lin.rss == pytest.approx(np.sqrt((c ** 2).sum(axis=0)), abs=1e-15)
    assert np.all(lin.rss <= lin.worst + 1e-18) and np.all(np.abs(lin.signed) <= lin.worst + 1e-18)
    # all parameters at +T: the linear signed sum predicts the full chain to second order
    full = chain.deviation(THESIS)[0]
    assert np.max(np.abs(full - lin.signed)) < 0.01 * np.max(np.abs(lin.signed))


def test_monte_carlo_sigma_matches_rss_for_small_tolerances(chain):
    tol = ToleranceSet(THESIS)
    lin = linear_analysis(chain, tol)
    mc = monte_carlo(chain, tol, 20000, seed=7, percents=(0.135, 50.0, 99.865))
    # σ estimate from n = 20000 has relative standard error 1/sqrt(2n) = 0.5 %
    assert np.max(np.abs(3 * mc.std - lin.rss) / lin.rss) < 0.025
    assert np.max(np.abs(mc.mean)) < 0.05 * np.max(lin.rss)
    assert np.all(mc.percentiles[0.135] <= mc.percentiles[50.0]) and np.all(mc.percentiles[50.0] <= mc.percentiles[99.865])


def test_full_chain_departs_from_the_linearisation_at_second_order(chain):
    tol = ToleranceSet(THESIS).scaled(30.0)
    dq = sample_deviations(np.random.default_rng(2), tol, 20000)
    sens = chain.sensitivities()
    residual = chain.deviation(dq) - sum(np.outer(dq[k], sens[k]) for k in PARAMS)
    h = 1e-5
    second = {k: (chain.stroke({k: h}) - 2 * chain.stroke({}) + chain.stroke({k: -h}))[0] / h ** 2 for k in PARAMS}
    predicted = sum(0.5 * second[k] * (tol.T[k] / 3) ** 2 for k in PARAMS)  # E[½ Σ s_kk σ_k²], cross terms 0
    se = residual.std(axis=0) / np.sqrt(residual.shape[0])
    assert np.max(np.abs(predicted)) > 1e-5
    assert np.max(np.abs(residual.mean(axis=0) - predicted) / (se + 1e-12)) < 5.0


def test_clearance_law_is_exponential_and_shifts_the_stroke(chain):
    rng = np.random.default_rng(3)
    lam = 60e3
    c = sample_clearance(rng, lam, 200_000)
    assert c.mean() == pytest.approx(1 / lam, rel=0.01) and c.std() == pytest.approx(1 / lam, rel=0.01)
    cut = sample_clearance(rng, lam, 200_000, limit=0.05e-3)
    assert cut.max() <= 0.05e-3 and np.mean(cut > 0.025e-3) == pytest.approx(
        (np.exp(-lam * 0.025e-3) - np.exp(-lam * 0.05e-3)) / (1 - np.exp(-lam * 0.05e-3)), abs=0.005)
    with_c = monte_carlo(chain, ToleranceSet(THESIS, lam), 20000, seed=11)
    sens_r = chain.sensitivities()["r"]
    # mean Δs ≈ ∂s/∂r · (−1/λ): the loose roller follows r − c
    assert with_c.mean == pytest.approx(-sens_r / lam, abs=0.05 * np.max(np.abs(sens_r)) / lam)


def test_streamed_statistics_equal_numpy_on_all_samples(chain):
    """Tasks of 700 machines (the last one shorter), statistics folded pass by pass: the percentiles are
    numpy's on the whole sample set bit for bit, the moments to rounding."""
    tol = ToleranceSet(THESIS, 60e3)
    mc = monte_carlo(chain, tol, 3000, seed=5, task_samples=700, percents=(0.135, 2.5, 50.0, 99.865))
    every = np.concatenate([b for source in tasks(chain, tol, 3000, 5, 700) for b in source.blocks()])
    assert every.shape == (3000, PHI.size) and mc.n == 3000
    for p, values in mc.percentiles.items():
        np.testing.assert_array_equal(values, np.percentile(every, p, axis=0))
    np.testing.assert_allclose(mc.mean, every.mean(axis=0), rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(mc.std, every.std(axis=0, ddof=1), rtol=1e-10)
    np.testing.assert_array_equal(mc.maximum, every.max(axis=0))
    other = monte_carlo(chain, tol, 3000, seed=6, task_samples=700)
    assert not np.array_equal(mc.mean, other.mean)


def test_fourbar_influence_factors_match_finite_differences():
    phi = np.radians(np.arange(0.0, 360.0, 10.0))
    res = influence_factors(EXAMPLE_LENGTHS, EXAMPLE_TOLERANCES, phi)
    h = 1e-8
    for k in range(4):
        up, dn = list(EXAMPLE_LENGTHS), list(EXAMPLE_LENGTHS)
        up[k] += h
        dn[k] -= h
        fd = (rocker_angle(tuple(up), phi) - rocker_angle(tuple(dn), phi)) / (2 * h)
        assert res.factors[k] == pytest.approx(fd, rel=1e-5, abs=1e-4)
    # the rocker closes the loop: coupler length between crank and rocker ends equals l3
    l1, l2, l3, l4 = EXAMPLE_LENGTHS
    p = l2 * np.exp(1j * phi)
    q = l1 + l4 * np.exp(1j * res.psi)
    assert np.abs(q - p) == pytest.approx(np.full(phi.size, l3), abs=1e-12)
    assert np.all(res.rss <= res.worst) and 1e-3 < np.max(res.worst) < 0.1  # a few mrad for 0.2–0.5 mm


def test_bad_inputs_raise_clear_errors(tmp_path, chain):
    with pytest.raises(SingularPositionError, match="cannot be assembled"):
        rocker_angle((0.100, 0.030, 0.020, 0.010), np.array([0.0]))
    with pytest.raises(SingularPositionError, match="φ ="):
        chain.stroke({"r": 0.2})
    with pytest.raises(ValueError, match="unknown chain parameter"):
        chain.stroke({"L5": 1e-6})
    with pytest.raises(ValueError, match="lacks"):
        ToleranceSet({"x_A0": 1e-6})
    bad = tmp_path / "tol.toml"
    bad.write_text("[tolerances]\n" + "\n".join(f'{k} = "0.01 mm"' for k in PARAMS if k != "l4") + '\nl4 = "0.01 N"\n')
    with pytest.raises(SceneError, match="'l4'.*wrong dimension"):
        load_tolerances(bad)
    with pytest.raises(ValueError, match="n ≥ 2"):
        monte_carlo(chain, ToleranceSet(THESIS), 1, seed=1)
    with pytest.raises(ValueError, match="task_samples ≥ 1"):
        monte_carlo(chain, ToleranceSet(THESIS), 10, seed=1, task_samples=0)


def test_cli_prints_the_tables_and_writes_the_chart(tmp_path, capsys):
    from rig.cli import main
    assert main(["tolerance", "--samples", "400", "-o", str(tmp_path)]) == 0
    text = capsys.readouterr().out
    assert "worst case" in text and "RSS" in text and "3σ/RSS" in text and "four-bar" in text
    assert (tmp_path / "pin_insertion.tolerance.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    clutch = Path(__file__).resolve().parents[2] / "data" / "scenes" / "clutch_startup.toml"
    assert main(["tolerance", str(clutch), "--samples", "10", "-o", str(tmp_path)]) == 2
    assert "needs plant \"cam_bar\"" in capsys.readouterr().err


def test_a_band_from_too_few_machines_says_what_it_is():
    """The 0.135–99.865 % band of a small Monte Carlo is flagged: below ~741 machines it is the sample's range,
    below ~7400 (fewer than 10 machines expected in each tail) a rough estimate; from there no note."""
    from rig.plants.cam_bar.tolerance_report import tail_note
    assert "the sample's range" in tail_note(10)
    assert "rough estimate" in tail_note(2000) and "7408 samples" in tail_note(2000)
    assert tail_note(7408) == "" and tail_note(10**6) == ""


def test_a_set_whose_tolerances_allow_machines_that_cannot_be_built_says_how_many(chain):
    """The Monte-Carlo run stopped at the first machine that cannot be assembled, naming its angle only: it now says
    which share of the set fails (counted machine by machine, here checked against the chain's own per-machine
    evaluation)."""
    tol = ToleranceSet({**{k: 1e-6 for k in PARAMS}, "r": 0.06})       # ±60 mm on the pitch radius
    mask = buildable_probe(chain, tol, 5)
    bad = int(np.count_nonzero(~mask))
    assert 0 < bad < PROBE
    dq = sample_deviations(np.random.default_rng(5), tol, PROBE)
    for i in range(300):                                                # the same draws, one machine at a time
        one = {k: v[i] for k, v in dq.items()}
        try:
            chain.stroke(one)
            built = True
        except SingularPositionError:
            built = False
        assert built == mask[i]
    with pytest.raises(SingularPositionError, match=rf"{bad} of {PROBE} machines drawn from these tolerances "
                                                    rf"\({100 * bad / PROBE:.3g} %\) cannot be assembled"):
        monte_carlo(chain, tol, 2000, 5)


def test_the_clearance_run_shares_no_machines_with_the_next_seeds_run(chain):
    """The clearance run drew from seed + 1: every lengths deviation of seed s's clearance run was the lengths-only
    run of seed s + 1 (studies at adjacent seeds not independent; an audit). It has a stream of its own."""
    from rig.plants.cam_bar.tolerance_report import clearance_stream
    tol = ToleranceSet(THESIS)
    (clear,), (next_seed,) = tasks(chain, tol, 500, clearance_stream(11)), tasks(chain, tol, 500, 12)
    stream = clearance_stream(11)
    (same,) = tasks(chain, tol, 500, stream)
    (again,) = tasks(chain, tol, 500, stream)            # the same object twice: the same machines (spawn counts)
    assert again.seed.spawn_key == same.seed.spawn_key
    drawn = [np.stack(list(sample_deviations(np.random.default_rng(t.seed), tol, 500).values()))
             for t in (clear, next_seed, same)]
    assert not np.any(np.isclose(drawn[0], drawn[1], rtol=0.0, atol=1e-15)) and np.array_equal(drawn[0], drawn[2])
