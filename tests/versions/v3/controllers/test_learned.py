"""scftc-v3's learned battery: rma_student, rma_dob and e2e_ppo, with their committed weights
(numba inference, no torch at evaluation). Each loads with its provenance, flies the protocol,
refuses another version, and the students identify a dead wheel on a train episode."""

from __future__ import annotations

import numpy as np
import pytest

from scftc_cli.baselines.checker import check_controller
from scftc_cli.errors import UsageError
from scftc_cli.registry import make_controller
from scftc_cli.sim import testbed as testbeds
from scftc_cli.sim.rollout import rollout
from scftc_cli.versions.v3.controllers.rma import RMADob, RMAStudent
from scftc_cli.versions.v3.spec import V3
from tests.versions.committed import check_committed_weights

V = V3.version
LEARNED = ("rma_student", "rma_dob", "e2e_ppo")
BED = testbeds.testbed(V)


@pytest.mark.parametrize("name", LEARNED)
def test_committed_weights_load_with_provenance(name: str) -> None:
    check_committed_weights(V, name)


@pytest.mark.parametrize("name", LEARNED)
def test_each_flies_the_protocol_and_refuses_another_version(name: str) -> None:
    check_controller(make_controller(name, V), benchmark=V, classes=("gain_bias", "loss"))
    v2_episodes = testbeds.testbed("scftc-v2").draw("train", "gain", n_faults=1, n_seeds=1)
    with pytest.raises(UsageError):
        rollout(make_controller(name, V), v2_episodes)


@pytest.mark.slow
@pytest.mark.parametrize("student", [RMAStudent, RMADob])
def test_the_students_find_the_dead_wheel_of_a_train_loss_episode(student) -> None:
    episodes = BED.draw("train", "loss", n_faults=4, n_seeds=1)
    controller = student()
    rollout(controller, episodes)
    dead = np.asarray(episodes.fault.gain) == 0.0
    assert dead.sum(axis=1).tolist() == [1, 1, 1, 1]
    # the latched estimate of the dead wheel, after the whole episode, is within the dead band
    gain = controller.gain
    assert np.all(np.abs(gain[dead]) < controller.config.dead_below)
    assert np.all(np.abs(gain[~dead] - np.asarray(episodes.fault.gain)[~dead]) < 0.2)
