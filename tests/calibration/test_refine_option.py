"""``refine``: the maximum-likelihood refinement of the optimum in a calibration (issue 35), opt-in."""
from __future__ import annotations

import numpy as np
import pytest
from _util import run

from handeye_cli import calibrate, document
from handeye_cli.errors import ConfigError
from handeye_cli.simulation.arm import simulate_arm
from handeye_cli.simulation.ground import simulate_ground


@pytest.fixture(scope="module")
def capture() -> object:
    return simulate_arm(15, seed=3)


@pytest.fixture(scope="module")
def both(capture) -> tuple[object, object]:
    flags = {"invert_a": capture.invert_a, "invert_b": capture.invert_b}
    return calibrate(capture.robot, capture.camera, **flags), calibrate(capture.robot, capture.camera, refine=True,
                                                                        **flags)


def test_the_refined_result_keeps_the_optimum_it_started_from_and_its_certificate(both) -> None:
    """The optimum is the unrefined run's, bit for bit; the document's solver block has it (pose, cost (8)) and
    its certificate, marked ``of: optimum``, beside ``refined``; the refined pose costs more in cost (8) and less
    in the likelihood, and is another pose; the run without the option has neither key."""
    plain, refined = both
    assert refined.solution.optimum is not None and refined.refinement is not None
    assert np.array_equal(refined.solution.optimum.matrix, plain.matrix)
    assert not np.allclose(refined.matrix, plain.matrix, atol=1e-12)
    solver = document(refined)["solver"]
    assert solver["certificate"]["of"] == "optimum" and solver["certificate"]["certified"] is True
    assert solver["optimum"]["cost"] == pytest.approx(plain.solution.cost, rel=1e-12)
    assert np.allclose(solver["optimum"]["quaternion_xyzw"], plain.quaternion_xyzw, atol=1e-15)
    assert refined.solution.cost >= plain.solution.cost                 # the optimum of cost (8) is the lowest
    account = solver["refined"]
    assert account["converged"] and account["cost"] <= account["cost_at_optimum"]
    assert account["samples"] == len(np.unique(np.r_[refined.pairs.i, refined.pairs.j]))
    assert 0 < account["change_from_optimum"]["rotation_deg"] < 0.5
    assert len(account["sigma"]["rotation_deg"]) == 3 and all(s > 0 for s in account["sigma"]["translation_m"])
    assert "refined" not in document(plain)["solver"] and "optimum" not in document(plain)["solver"]
    assert document(refined)["settings"]["options"]["refine"] is True
    assert document(plain)["settings"]["options"]["refine"] is False


def test_the_refined_result_passes_the_same_checks(both) -> None:
    """The fit test and the checks run on the pose written: the refined one passes where the optimum does."""
    plain, refined = both
    assert plain.diagnostics.fit.passed and refined.diagnostics.fit.passed
    assert refined.warnings == plain.warnings


@pytest.mark.parametrize(("keywords", "words"), [({"method": "park"}, "park does not claim"),
                                                  ({"prior": "nominal.urdf"}, "no prior term")])
def test_refine_with_another_method_or_a_prior_is_refused(keywords, words) -> None:
    with pytest.raises(ConfigError, match=words) as caught:
        calibrate(None, None, refine=True, **keywords)
    assert "refine" in str(caught.value) and "--" not in str(caught.value)


def test_the_command_line_refuses_it_in_one_line(capsys) -> None:
    code, out, err = run(capsys, "calibrate", "sample_data/rig_a.tum", "sample_data/rig_b.tum", "--refine",
                         "--method", "park")
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1
    assert "--refine" in err and "--method dqopt" in err


def test_planar_motion_is_not_refined_and_says_so() -> None:
    """A ground robot: the reduced in-plane solve is the result, and a warning says the refinement did not run."""
    rec = simulate_ground("diff-drive", seed=0)
    cal = calibrate(rec.base, rec.sensor, refine=True)
    assert cal.refinement is None and cal.diagnostics.subspace.axis_a is not None
    assert any(w.startswith("not refined: planar motion") for w in cal.warnings)


def test_compare_shows_the_refined_estimate_beside_the_optimum(capsys) -> None:
    """``handeye compare --refine``: the table has the calibration's refined estimate as its own row (without the
    flag it has none), and the optimum's row is dqopt's as before."""
    import json

    code, out, _ = run(capsys, "compare", "sample_data/rig_a.tum", "sample_data/rig_b.tum", "--refine", "--format",
                       "json")
    assert code == 0
    rows = {r["method"]: r for r in json.loads(out)["methods"]}
    assert "dqopt refined" in rows and rows["dqopt"]["vs_dqopt_deg"] == 0.0
    assert 0 < rows["dqopt refined"]["vs_dqopt_deg"] < 0.1 and rows["dqopt refined"]["milliseconds"] > 0
    code, out, _ = run(capsys, "compare", "sample_data/rig_a.tum", "sample_data/rig_b.tum", "--format", "json")
    assert code == 0 and "dqopt refined" not in {r["method"] for r in json.loads(out)["methods"]}
