"""A fit from Python is the CLI's fit: the same numbers to the last digit, the same options, the same
messages. The CLI runs as a subprocess (strut identify ... --json) on the same session."""
import json
import math
import subprocess
import sys

import numpy as np
import pytest

import strut
from conftest import run_strut


def same(a, b):
    """Exactly equal, JSON's null standing for a non-finite number."""
    if a is None or b is None:
        return (a is None or (isinstance(a, float) and not math.isfinite(a))) and \
               (b is None or (isinstance(b, float) and not math.isfinite(b)))
    return a == b


@pytest.fixture(scope="module")
def fits(lab, tmp_path_factory):
    """The CLI's JSON and the Python fit of the same session with the same options, twice: with the
    defaults, and with options that change the fit."""
    out = tmp_path_factory.mktemp("fits")
    session = lab / "unit12.h5"
    cases = {}
    for name, words, kwargs in [
        ("defaults", [], {}),
        ("options", ["--model", "1dof+heat-exchange", "--estimate", "paper", "--n", "400", "--calibration", "none",
                     "--exclude", "q3:pressure"],
         dict(model="1dof+heat-exchange", estimate="paper", n=400, calibration="none", exclude=["q3:pressure"])),
    ]:
        cli_json = out / f"{name}-cli.json"
        py_json = out / f"{name}-py.json"
        run_strut("identify", session, *words, "--no-progress", "--json", cli_json)
        fit = strut.identify(session, json=py_json, **kwargs)
        cases[name] = (json.loads(cli_json.read_text()), fit, cli_json, py_json)
    return cases


@pytest.mark.parametrize("case", ["defaults", "options"])
def test_fit_equals_the_cli_json_to_the_last_digit(fits, case):
    cli, fit, cli_json, py_json = fits[case]
    # The parameter table comes from the C++ summary itself, not from the JSON: every number equal.
    p = fit.parameters
    index = list(p.index) if strut.has_pandas() else list(p["index"])
    assert index == [x["index"] for x in cli["parameters"]]
    for row, x in enumerate(cli["parameters"]):
        for field in ("value", "sd", "sd_input_noise_factor", "sd_misfit_factor", "sd_calibration"):
            mine = float(p[field].iloc[row] if strut.has_pandas() else p[field][row])
            assert same(mine, x[field]), (x["index"], field, mine, x[field])
        assert bool(p["estimated"].iloc[row] if strut.has_pandas() else p["estimated"][row]) == x["estimated"]
    for c in cli["channels"]:
        mine = fit.channels.loc[c["name"]] if strut.has_pandas() else None
        if mine is not None:
            for field in ("variance", "noise_floor_variance", "rms", "noise_ratio", "noise_ratio_sd", "noise_floor_limit"):
                assert same(float(mine[field]), c[field]), (c["name"], field)
    for field in ("loglik", "aic", "bic", "iterations", "observations", "verdict", "verdict_text", "model", "converged"):
        assert same(getattr(fit, field), cli[field]), field
    # The whole record, every field and number; and json= writes the CLI's file byte for byte.
    assert fit.to_json() == cli
    assert py_json.read_bytes() == cli_json.read_bytes()


def test_the_options_changed_the_fit(fits):
    # A guard on the comparison above: the two cases are different fits, so the options did reach it.
    assert fits["options"][1].model == "1dof+heat-exchange"
    assert fits["defaults"][1].loglik != fits["options"][1].loglik
    assert fits["options"][1].to_json()["excluded"] == ["q3:pressure"]


def test_intervals_are_the_reports_plus_minus_1_96_sd(fits):
    _, fit, _, _ = fits["defaults"]
    p = fit.parameters
    if strut.has_pandas():
        estimated = p[p["estimated"]]
        assert np.allclose(estimated["upper"] - estimated["value"], 1.96 * estimated["sd"], rtol=1e-12, atol=0)
        assert p[~p["estimated"]]["lower"].isna().all()


def test_experiments_carry_the_records_the_report_plots(fits):
    cli, fit, _, _ = fits["defaults"]
    experiments = fit.experiments
    assert list(experiments) == [e["label"] for e in cli["experiments"]]
    for x in cli["experiments"]:
        e = experiments[x["label"]]
        for channel, figures in e.channels.items():
            assert same(figures["rms"], x[channel]["rms"])
        for channel, residual in e.residual.items():
            assert residual.shape == e.phase.shape
            assert np.allclose(e.predicted[channel] + residual, e.measured[channel], rtol=0, atol=1e-9 * np.abs(e.measured[channel]).max())
            assert math.isclose(float(np.sqrt(np.mean(residual ** 2))), x[channel]["rms"], rel_tol=1e-9)


def test_an_unknown_keyword_is_a_clear_error(lab):
    with pytest.raises(TypeError) as raised:
        strut.identify(lab / "unit12.h5", modle="1dof")
    message = str(raised.value)
    assert "modle" in message and "--modle" in message and "model" in message and "estimate_input" in message


def test_a_flag_takes_true_or_false(lab):
    with pytest.raises(TypeError) as raised:
        strut.identify(lab / "unit12.h5", no_progress="yes")
    assert "no_progress" in str(raised.value)


@pytest.mark.parametrize("kwargs,words", [
    (dict(scheme="central3"), ["--scheme", "central3"]),    # refused by the option's own check
    (dict(n=3), ["--n", "3"]),                              # out of the option's range
    (dict(calibration="forse=0.2%"), ["--calibration", "forse=0.2%"]),  # refused by the library
    (dict(set="theta4=-1"), ["--set", "theta4=-1"]),         # outside the parameter's physical range
])
def test_errors_carry_the_cli_message(lab, kwargs, words):
    session = lab / "unit12.h5"
    cli = run_strut("identify", session, *words, "--no-progress", check=False)
    assert cli.returncode == 1
    with pytest.raises(ValueError) as raised:
        strut.identify(session, **kwargs)
    assert str(raised.value) and str(raised.value) in cli.stderr, (str(raised.value), cli.stderr)


def test_keywords_are_the_cli_long_options_with_their_defaults():
    o = strut.options("identify")
    assert o["estimate_input"]["option"] == "--estimate-input"
    assert o["input_harmonics"]["default"] == "20"
    assert o["model"]["default"] == "2dof"
    assert o["no_progress"]["flag"]
    help_text = run_strut("identify", "--help").stdout
    for keyword, option in o.items():
        assert option["option"] in help_text, keyword


def test_without_pandas_tables_are_dicts_of_numpy_arrays(lab):
    script = (
        "import strut, numpy\n"
        "assert not strut.has_pandas()\n"
        f"fit = strut.identify({str(lab / 'unit12.h5')!r})\n"
        "p = fit.parameters\n"
        "assert isinstance(p, dict) and isinstance(p['value'], numpy.ndarray), type(p)\n"
        "assert list(p['index'])[:2] == ['theta1', 'theta2'], p['index']\n"
        "print(len(p['value']))\n")
    import os
    env = dict(os.environ, STRUT_NO_PANDAS="1")
    r = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env)
    assert r.returncode == 0, r.stderr
    assert int(r.stdout) > 10


def test_the_report_is_written_and_shown_inline(fits, tmp_path):
    _, fit, _, _ = fits["defaults"]
    path = tmp_path / "fit.html"
    fit.write_report(path)
    text = path.read_text()
    assert "<html" in text.lower() and "theta4" in text
    inline = fit._repr_html_()
    assert inline.startswith("<iframe srcdoc=") and "theta4" in inline
    assert "at-noise-floor" in fit.verdict or fit.verdict in ("above-noise-floor", "not-converged")
