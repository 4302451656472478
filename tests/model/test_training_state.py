"""An interrupted training goes on from its saved state to the model an uninterrupted run makes."""

import numpy as np
import pytest
import torch

from dexlite_pipeline.model.config import TrainConfig
from dexlite_pipeline.model.data import build_training_data, split_validation
from dexlite_pipeline.model.training import train_cvae
from dexlite_pipeline.model.training_state import TrainingStateFile


@pytest.fixture(scope="module")
def setup(hand, tiny_assets, request):
    grasps = request.getfixturevalue("make_grasps")(hand, 8, seed=3)
    return grasps, build_training_data(grasps, tiny_assets, hand)


def _config(small_model_config, **overrides):
    values = dict(epochs=5, max_steps=0, batch_size=2, clouds_per_batch=2, points_per_cloud=64, learning_rate=3e-3, validation_fraction=0.25)
    values.update(overrides)
    return TrainConfig(model=small_model_config, **values)


def _unused_energies(*args, **kwargs):
    raise AssertionError("no energy is weighted")


class Interrupted(Exception):
    pass


def _stop_after(epoch):
    def on_epoch(row):
        if row["epoch"] == epoch:
            raise Interrupted
    return on_epoch


def _same_weights(a, b):
    return all(torch.equal(x, y) for x, y in zip(a.state_dict().values(), b.state_dict().values()))


def test_a_run_stopped_after_an_epoch_goes_on_to_the_uninterrupted_model(tmp_path, setup, small_model_config):
    grasps, data = setup
    train, val = split_validation(len(grasps), 0.25, seed=0)
    config = _config(small_model_config)
    whole = train_cvae(data, train, val, config, _unused_energies, seed=4)

    state = TrainingStateFile(tmp_path / "cvae.pt.state", every_s=0)
    with pytest.raises(Interrupted):
        train_cvae(data, train, val, config, _unused_energies, seed=4, on_epoch=_stop_after(2), state_file=state)
    assert state.path.exists()
    resumed = train_cvae(data, train, val, config, _unused_energies, seed=4, state_file=TrainingStateFile(state.path, every_s=0))

    assert resumed.resumed_after_epoch == 2 and whole.resumed_after_epoch == 0
    assert resumed.steps == whole.steps
    assert _same_weights(resumed.model, whole.model)
    strip = lambda rows: [{k: v for k, v in row.items() if k != "seconds"} for row in rows]  # noqa: E731
    np.testing.assert_equal(strip(resumed.history), strip(whole.history))  # NaN: energies not weighted
    # not after the last epoch: a finished training leaves the state of its last saved epoch, which the stage removes
    assert torch.load(state.path, weights_only=True)["epoch"] == 4


def test_a_state_of_another_seed_or_data_is_not_used(tmp_path, setup, small_model_config):
    grasps, data = setup
    train, val = split_validation(len(grasps), 0.25, seed=0)
    config = _config(small_model_config, epochs=3)
    state = TrainingStateFile(tmp_path / "state", every_s=0)
    with pytest.raises(Interrupted):
        train_cvae(data, train, val, config, _unused_energies, seed=4, on_epoch=_stop_after(1), state_file=state)

    fresh = train_cvae(data, train, val, config, _unused_energies, seed=5)
    other_seed = train_cvae(data, train, val, config, _unused_energies, seed=5, state_file=TrainingStateFile(state.path, every_s=0))
    assert other_seed.resumed_after_epoch == 0 and _same_weights(other_seed.model, fresh.model)

    with pytest.raises(Interrupted):
        train_cvae(data, train, val, config, _unused_energies, seed=4, on_epoch=_stop_after(1), state_file=TrainingStateFile(state.path, every_s=0))
    fewer = train_cvae(data, train[:-1], val, config, _unused_energies, seed=4, state_file=TrainingStateFile(state.path, every_s=0))
    assert fewer.resumed_after_epoch == 0
    other_context = TrainingStateFile(state.path, every_s=0, context={"self_penetration_margin_m": 0.01})
    with pytest.raises(Interrupted):
        train_cvae(data, train, val, config, _unused_energies, seed=4, on_epoch=_stop_after(1), state_file=TrainingStateFile(state.path, every_s=0))
    assert train_cvae(data, train, val, config, _unused_energies, seed=4, state_file=other_context).resumed_after_epoch == 0


def test_an_unreadable_state_is_set_aside(tmp_path, setup, small_model_config):
    grasps, data = setup
    path = tmp_path / "state"
    path.write_bytes(b"not a torch file")
    result = train_cvae(data, np.arange(len(grasps)), np.zeros(0, np.int64), _config(small_model_config, epochs=1), _unused_energies, seed=0,
                        state_file=TrainingStateFile(path, every_s=0))
    assert result.resumed_after_epoch == 0 and len(result.history) == 1


def test_the_interval_spaces_the_saves(tmp_path, setup, small_model_config):
    grasps, data = setup
    state = TrainingStateFile(tmp_path / "state", every_s=3600)
    train_cvae(data, np.arange(len(grasps)), np.zeros(0, np.int64), _config(small_model_config, epochs=3), _unused_energies, seed=0, state_file=state)
    assert not state.path.exists()  # no epoch ended an hour after the start
    with pytest.raises(ValueError, match="every_s"):
        TrainingStateFile(tmp_path / "s", every_s=-1)
