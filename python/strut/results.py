"""What identify, discover, qc and predict_drop return: the C++ results with tables, JSON and reports."""
import html as _html
import json
import os
import tempfile

import numpy as np

from .tables import has_pandas, html, rows_table, table

#: The 95 % interval the reports show: value +- 1.96 sd (report/src/fit_report.cpp).
INTERVAL_Z = 1.96


class _Report:
    """The HTML report of a result: written to a file, or shown inline in Jupyter (_repr_html_)."""

    def _write_report(self, path):
        raise NotImplementedError

    def write_report(self, path):
        """Writes the self-contained HTML report (what --report writes)."""
        self._write_report(os.fspath(path))

    def report_html(self):
        """The HTML report as text."""
        with tempfile.TemporaryDirectory() as folder:
            path = os.path.join(folder, "report.html")
            self._write_report(path)
            with open(path, encoding="utf-8") as f:
                return f.read()

    def _repr_html_(self):
        # The report is a whole document with its scripts: an iframe keeps it apart from the notebook's page.
        return (f'<iframe srcdoc="{_html.escape(self.report_html(), quote=True)}" '
                'style="width:100%;height:720px;border:1px solid #ccc"></iframe>')


class ExperimentFit:
    """One periodic experiment of a fit: its figures per channel (`channels`: mean, sd, rms and noise
    ratio of the residuals), and the averaged records the report plots at the cyclic `phase`:
    `measured`, `predicted` (measured - residual) and `residual`, per fitted channel."""

    def __init__(self, row):
        self.label = row["label"]
        self.group, self.session = row["group"], row["session"]
        self.frequency, self.amplitude, self.static_position = row["frequency"], row["amplitude"], row["static_position"]
        self.converged, self.error = row["converged"], row["error"]
        self.channels = row["channels"]
        self.phase = row["phase"]
        self.measured = row["measured"]
        self.residual = row["residual"]
        self.predicted = {c: self.measured[c] - r for c, r in self.residual.items()}
        self.noise_variance = row["noise_variance"]

    def __repr__(self):
        return f"<strut.ExperimentFit {self.label!r} {self.frequency:g} Hz, channels {', '.join(self.residual)}>"


class Fit(_Report):
    """A fit: `parameters` (with the 95 % interval), `channels`, `experiments`, `figures`,
    `correlation`; `to_json()` is the JSON `strut identify --json` writes, `write_report()` its report."""

    def __init__(self, native, title=None):
        self._native = native
        self._title = title or f"strut identify: {native.model}"

    model = property(lambda self: self._native.model)
    verdict = property(lambda self: self._native.verdict, doc="at-noise-floor, above-noise-floor or not-converged")
    verdict_text = property(lambda self: self._native.verdict_text)
    converged = property(lambda self: self._native.converged)
    iterations = property(lambda self: self._native.iterations)
    loglik = property(lambda self: self._native.loglik)
    aic = property(lambda self: self._native.aic)
    bic = property(lambda self: self._native.bic)
    observations = property(lambda self: self._native.observations)
    warnings = property(lambda self: self._native.warnings)
    calibration = property(lambda self: self._native.calibration)

    @property
    def parameters(self):
        """Every parameter (index theta1...): name, unit, value, sd, estimated, the sd factors, and the
        95 % interval lower, upper (value -+ 1.96 sd; NaN where fixed). Indexed by `index`."""
        c = self._native.parameter_columns()
        estimated = np.asarray(c["estimated"], dtype=bool)
        half = np.where(estimated, INTERVAL_Z * c["sd"], np.nan)
        c["lower"], c["upper"] = c["value"] - half, c["value"] + half
        return table(c, "index")

    @property
    def channels(self):
        """Per fitted channel: residual variance, noise-floor variance, rms, pooled noise ratio and its limit."""
        return rows_table(self._native.channel_rows(), "name")

    @property
    def experiments(self):
        """The periodic experiments (label -> ExperimentFit) with their averaged records."""
        return {row["label"]: ExperimentFit(row) for row in self._native.experiment_rows()}

    @property
    def figures(self):
        """Per experiment and channel: mean, sd, rms and noise ratio of the residuals (one row each)."""
        rows = []
        for e in self._native.experiment_rows():
            for channel, f in e["channels"].items():
                rows.append({"experiment": e["label"], "channel": channel, "frequency": e["frequency"],
                             "amplitude": e["amplitude"], "static_position": e["static_position"], **f})
        return rows_table(rows)

    @property
    def correlation(self):
        """The estimated parameters' correlation (a DataFrame; without pandas (names, matrix))."""
        names, matrix = self._native.correlation()
        if not has_pandas():
            return names, np.asarray(matrix)
        import pandas as pd
        return pd.DataFrame(np.asarray(matrix), index=names, columns=names)

    def to_json(self):
        """The fit as `strut identify --json` writes it (docs/identification.md), as Python data."""
        return json.loads(self._native.json_text)

    def write_json(self, path):
        """Writes to_json() as the CLI lays its JSON out (one space of indent, a final newline)."""
        with open(os.fspath(path), "w", encoding="utf-8") as f:
            f.write(json.dumps(self.to_json(), indent=1, ensure_ascii=False) + "\n")

    def _write_report(self, path):
        self._native.write_report(path, self._title)

    def __str__(self):
        return self._native.full_report

    def __repr__(self):
        return f"<strut.Fit {self.model}: {self.verdict}, {len(self._native.experiment_rows())} periodic experiments>"


class Discovery(_Report):
    """What `strut discover` found: `missing` (terms added), `final_model`, `conclusion`, `steps`,
    `ambiguities` (explanations that fit alike, each with its decisive `test`), `decision` (what
    `decide=` found, or None), the `baseline` and `final_fit` as Fits, `json` as `--json` writes it."""

    def __init__(self, native):
        self._native = native

    conclusion = property(lambda self: self._native.conclusion)
    missing = property(lambda self: self._native.missing)
    nothing_missing = property(lambda self: self._native.nothing_missing)
    final_model = property(lambda self: self._native.final_model)
    json = property(lambda self: self._native.json)
    baseline = property(lambda self: Fit(self._native.baseline, f"strut discover: baseline {self._native.baseline.model}"))
    final_fit = property(lambda self: Fit(self._native.final_fit, f"strut discover: {self._native.final_model}"))

    @property
    def steps(self):
        return self.json.get("steps", [])

    @property
    def ambiguities(self):
        return self.json.get("ambiguities", [])

    @property
    def decision(self):
        return self.json.get("decision")

    def _write_report(self, path):
        self._native.write_report(path)

    def __repr__(self):
        return f"<strut.Discovery {self.final_model}: missing {self.missing or 'nothing'}>"


class QcDecision(_Report):
    """A QC decision: `verdict` (PASS, FAIL, UNDECIDED), `reasons`, `quantities` (a table), the `fit`
    it decided on (None when none was made), `json` as `strut qc --json` writes it."""

    def __init__(self, native):
        self._native = native

    verdict = property(lambda self: self._native.verdict)
    reasons = property(lambda self: self._native.reasons)
    json = property(lambda self: self._native.json)

    @property
    def fit(self):
        native = self._native.fit
        return None if native is None else Fit(native, "strut qc")

    @property
    def quantities(self):
        return rows_table(self.json.get("quantities", []))

    def _write_report(self, path):
        self._native.write_report(path)

    def __str__(self):
        return self._native.table

    def __repr__(self):
        return f"<strut.QcDecision {self.verdict}: {'; '.join(self.reasons)}>"


class DropPrediction(_Report):
    """A drop predicted from a fit: `figures` (the table the CLI prints), `trace` (time, stroke, force,
    ... as numpy arrays), `json` as `strut predict drop --json` writes it."""

    def __init__(self, native):
        self._native = native

    json = property(lambda self: self._native.json)

    @property
    def figures(self):
        header, rows = self._native.table
        return table({h: [r[i] for r in rows] for i, h in enumerate(header)})

    @property
    def trace(self):
        return table(self._native.trace)

    def _write_report(self, path):
        self._native.write_report(path)

    def __repr__(self):
        return "<strut.DropPrediction>"
