"""sim_matrix, qc, predict_drop and discover from Python against the same commands of the CLI."""
import json
import math

import numpy as np
import pytest

import strut
from conftest import run_strut


def test_sim_matrix_records_the_session_the_cli_records(lab, tmp_path):
    mine = tmp_path / "py.h5"
    session = strut.sim_matrix(draw=12, matrix=lab / "qc.toml", output=mine)
    assert session.path == str(mine)
    cli = strut.read_session(lab / "unit12.h5")  # strut sim matrix --draw 12 --matrix qc.toml (conftest)
    assert list(session.experiments) == list(cli.experiments)
    for label, e in cli.experiments.items():
        assert np.array_equal(session[label].time, e.time)
        for channel, samples in e.channels.items():
            assert np.array_equal(session[label][channel], samples), (label, channel)
    # What it returned is what it wrote.
    written = strut.read_session(mine)
    for label, e in written.experiments.items():
        assert np.array_equal(session[label]["force"], e["force"])
    # Another seed of the noise is another record: the keyword reached the rig.
    other = strut.sim_matrix(draw=12, seed=2, matrix=lab / "qc.toml", output=tmp_path / "seed2.h5")
    first = next(iter(cli.experiments))
    assert not np.array_equal(other[first]["force"], cli[first]["force"])


def test_sim_matrix_refuses_what_the_cli_refuses(lab, tmp_path):
    cli = run_strut("sim", "matrix", "--draw", 12, check=False)
    with pytest.raises(strut.OptionError) as raised:
        strut.sim_matrix(draw=12)
    assert str(raised.value) in cli.stderr and "output" in str(raised.value)
    existing = lab / "unit12.h5"
    cli = run_strut("sim", "matrix", "--matrix", lab / "qc.toml", "-o", existing, check=False)
    with pytest.raises(ValueError) as raised:
        strut.sim_matrix(matrix=lab / "qc.toml", output=existing)
    assert str(raised.value) in cli.stderr and str(existing) in str(raised.value)
    with pytest.raises(ValueError) as raised:
        strut.sim_matrix(base="3dof", output=tmp_path / "x.h5")
    assert "--base" in str(raised.value)


def test_qc_decides_as_the_cli_decides(lab, tmp_path):
    cli_json = tmp_path / "qc.json"
    run_strut("qc", lab / "unit12.h5", "--reference", lab / "ref.toml", "--json", cli_json, check=False)
    cli = json.loads(cli_json.read_text())
    decision = strut.qc(lab / "unit12.h5", reference=lab / "ref.toml")
    assert decision.verdict == cli["verdict"]
    mine = decision.json
    mine.pop("seconds", None), cli.pop("seconds", None)  # wall time
    assert mine == cli
    assert decision.fit is not None and decision.fit.model == cli["model"]


def test_predict_drop_from_a_fit_object_equals_the_cli_from_its_json(lab, tmp_path):
    fit_json = tmp_path / "fit.json"
    run_strut("identify", lab / "unit12.h5", "--no-progress", "--json", fit_json)
    options = dict(mass=350, velocity=0.5, duration=2, no_intervals=True)
    cli_json = tmp_path / "drop.json"
    run_strut("predict", "drop", "--fit", fit_json, "--mass", 350, "--velocity", 0.5, "--duration", 2,
              "--no-intervals", "--json", cli_json)
    cli = json.loads(cli_json.read_text())
    fit = strut.identify(lab / "unit12.h5")
    drop = strut.predict_drop(fit=fit, **options)
    mine = drop.json
    assert mine["predicted"] == cli["predicted"]
    assert mine["mass"] == cli["mass"] == 350
    trace = drop.trace
    assert len(trace["time"]) > 100 and float(np.max(trace["stroke"])) > 0
    # The same from the file, as the CLI reads it.
    assert strut.predict_drop(fit=fit_json, **options).json["predicted"] == cli["predicted"]
    with pytest.raises(ValueError) as raised:
        strut.predict_drop(fit=fit, mass=0)
    assert "--mass" in str(raised.value)


def test_discover_finds_what_the_cli_finds(lab, tmp_path):
    cli_json = tmp_path / "discover.json"
    run_strut("discover", lab / "unit12.h5", "--model", "1dof", "--json", cli_json)
    cli = json.loads(cli_json.read_text())
    found = strut.discover(lab / "unit12.h5", model="1dof")
    assert found.json == cli
    assert found.missing == cli["missing"] and found.missing  # 1 dof leaves the heat exchange out
    assert found.final_fit.model == found.final_model
    assert found.baseline.verdict == "above-noise-floor" and found.final_fit.verdict == "at-noise-floor"
    assert found.ambiguities == cli["ambiguities"] and found.decision is None
