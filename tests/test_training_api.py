"""The training API: ``postproc.model.training.fit`` → ``TrainedModel`` (export, card, estimator) on
data measured on the simulated robot, and the estimators' scikit-learn conventions
(``estimator.Estimator``: parameters from the constructor's signature, fit returns self,
fitted state ends in ``_``)."""
from __future__ import annotations

import inspect
import json

import numpy as np
import pytest

from postproc.cli import main
from postproc.model.compensator import load_model
from postproc.measurements.csv import read_measurements, write_measurements
from postproc.calibration.planning import latin_hypercube
from postproc.calibration.simulator import SimulatedRobot
from postproc.model.training import ErrorModel, TrainedModel, fit
from postproc.model.training.estimator import Estimator
from postproc.model.training.features import previous_poses
from postproc.model.training.hybrid import HybridModel
from postproc.model.training.kinematic import KinematicModel
from postproc.settings import Settings

TINY = {"hidden": (6,), "epochs": 10, "population": 6, "generations": 3}  # a GPSO-DNN fitted in well under a second


@pytest.fixture(scope="module")
def measured(tmp_path_factory):
    """120 poses measured in plan order on a drawn simulated robot (its errors vary over space)."""
    path = tmp_path_factory.mktemp("api") / "measured.csv"
    poses = latin_hypercube(120, seed=0)
    write_measurements(path, poses, SimulatedRobot(seed=7).measure(poses, rng_seed=0))
    return path


@pytest.fixture(scope="module")
def kinematic(measured, tmp_path_factory):
    """The identification alone fitted by ``fit`` and exported."""
    trained = fit(measured, Settings().override(method="kinematic", val_fraction=0.1, seed=0))
    return trained, trained.export(tmp_path_factory.mktemp("kin") / "kin.onnx")


def _json(card: dict) -> dict:
    return json.loads(json.dumps(card, default=float))


def test_fit_exports_the_card_and_a_graph_that_predicts_as_the_estimator(kinematic, measured):
    trained, path = kinematic
    assert isinstance(trained, TrainedModel) and isinstance(trained.model, HybridModel)
    compensator = load_model(path)
    stored = {k: v for k, v in compensator.metadata.items() if k != "postproc_contract"}
    assert stored == _json({**trained.card, "name": "kin"})  # name None: the file's stem
    assert trained.card["accuracy"]["n_train"] == len(trained.train_rows) == 108
    assert trained.card["accuracy"]["val_mean_mm"] < trained.card["accuracy"]["val_uncompensated_mean_mm"] / 3
    poses = read_measurements(measured).poses
    previous = previous_poses(poses)
    want = trained.model.predict(poses, previous)
    assert np.ptp(want, axis=0).min() > 0.05  # a correction that varies over the space
    np.testing.assert_allclose(compensator.predict(poses, previous), want, atol=2e-3)


def test_fit_takes_measurements_or_a_path_and_leaves_them_as_they_were(measured):
    data = read_measurements(measured)
    before = data.measured.copy()
    a, b = fit(data, Settings().override(method="gpso"), **TINY), fit(measured, Settings().override(method="gpso"), **TINY)
    assert _json(a.card) == _json(b.card)
    np.testing.assert_array_equal(a.model.params_, b.model.params_)
    np.testing.assert_array_equal(data.measured, before)


def test_the_cli_writes_what_fit_exports(measured, tmp_path):
    """`postproc train` only maps its arguments to fit: the same bytes."""
    cli = tmp_path / "cli.onnx"
    assert main(["train", str(measured), "-o", str(cli), "-q", "--method", "plain", "--hidden", "5,3", "--epochs", "8",
                 "--seed", "3", "--robot", "KR500-sim", "--name", "m"]) == 0
    api = fit(measured, Settings().override(method="plain", robot="KR500-sim", name="m", hidden=(5, 3), epochs=8, seed=3)).export(tmp_path / "api.onnx")
    assert cli.read_bytes() == api.read_bytes()


def test_fit_refuses_what_train_refuses(measured):
    from postproc.core.diagnostics import PostprocError

    with pytest.raises(PostprocError, match="P317"):
        fit(measured, Settings().override(method="gpso", update="old.onnx"))
    with pytest.raises(PostprocError, match="P508"):
        fit(measured, Settings().override(method="hybrid", robot="UR5"))
    with pytest.raises(TypeError):
        fit(measured, Settings().override(method="gpso"), ensemble=3)  # a HybridModel parameter, not ErrorModel's
    with pytest.raises(ValueError, match="unknown method"):
        fit(measured, Settings().override(method="svm"))
    # the networks' options on an identified method: refused, not ignored (P516)
    with pytest.raises(PostprocError, match="P516.*--search"):
        fit(measured, Settings().override(method="hybrid", search=True))
    with pytest.raises(PostprocError, match="P516.*--optimizer"):
        fit(measured, Settings().override(method="kinematic", optimizer="adam"))


@pytest.mark.parametrize("cls", [ErrorModel, HybridModel, KinematicModel])
def test_parameters_are_the_constructor_signature(cls):
    from postproc.robot.description import load_description

    args = {"description": load_description()} if cls is not ErrorModel else {}
    model = cls(**args)
    names = [n for n in inspect.signature(cls.__init__).parameters if n != "self"]
    assert list(model.get_params()) == names
    assert set(vars(model)) == set(names)  # the constructor stores its parameters, nothing else
    again = cls(**model.get_params())
    assert again.get_params() == model.get_params()
    key = "seed" if "seed" in names else "prior"
    assert model.set_params(**{key: 5}) is model and model.get_params()[key] == 5
    with pytest.raises(ValueError, match="unknown parameter 'nope'"):
        model.set_params(nope=1)


def test_get_params_follows_a_subclass_signature():
    class Wider(ErrorModel):
        def __init__(self, width: int = 4, **rest):
            super().__init__(**rest)
            self.width = width

    assert list(Wider(width=9).get_params()) == ["width"]  # (**rest is no parameter of its own)
    assert issubclass(Wider, Estimator)


def test_a_clone_by_params_fits_the_same_and_fitted_state_ends_in_underscore(measured, kinematic):
    trained, _ = kinematic
    data = read_measurements(measured)
    t = trained.train_rows
    poses, errors = data.poses[t], data.errors[t]
    network = fit(data, Settings().override(method="gpso", val_fraction=0.1), **TINY)  # (the same split as the kinematic fixture's)
    np.testing.assert_array_equal(network.train_rows, t)
    for model, args in ((network.model, ()), (trained.model, (previous_poses(data.poses)[t],))):
        clone = type(model)(**model.get_params())
        assert clone.fit(poses, errors, *args) is clone
        fitted = set(vars(clone)) - set(clone.get_params())
        assert fitted and all(n.endswith("_") or n.startswith("_") for n in fitted), sorted(fitted)
        np.testing.assert_array_equal(clone.predict(poses), model.predict(poses))
