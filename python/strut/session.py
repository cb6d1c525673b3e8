"""Recorded sessions as numpy arrays, read by daq's session reader (the one every strut command uses)."""
import os

from . import _strut
from .tables import has_pandas, html, table


class Experiment:
    """One experiment of a session: `time` and `channels` (name -> samples, SI units) as numpy arrays,
    `units` per channel, and its attributes (`frequency`, `amplitude`, `static_position`, `sample_rate`,
    `kind`, ...; all of them in `metadata`)."""

    def __init__(self, data):
        self.time = data["time"]
        self.channels = {c["name"]: c["samples"] for c in data["channels"]}
        self.units = {c["name"]: c["units"] for c in data["channels"]}
        self.references = {c["name"]: c["reference"] for c in data["channels"] if c["reference"]}
        self.metadata = {k: v for k, v in data.items() if k not in ("time", "channels")}

    def __getattr__(self, name):
        metadata = self.__dict__.get("metadata", {})
        if name in metadata:
            return metadata[name]
        raise AttributeError(f"experiment has no attribute {name!r}")

    def __getitem__(self, channel):
        try:
            return self.channels[channel]
        except KeyError:
            raise KeyError(f"experiment {self.label!r} has no channel {channel!r} (it has {', '.join(self.channels)})") from None

    def to_frame(self):
        """time and every channel as columns (a DataFrame, or a dict without pandas)."""
        return table({"time": self.time, **self.channels})

    def __repr__(self):
        return (f"<strut.Experiment {self.label!r} {self.kind}: {len(self.time)} samples at {self.sample_rate:g} Hz, "
                f"channels {', '.join(self.channels)}>")


class Session:
    """A recorded session: `experiments` (label -> Experiment, in file order), the session's
    attributes (`damper_serial`, `rig`, `created_utc`, `profile`, `format_version`) and `metadata`
    (the extra root groups, e.g. a simulated session's /truth, as nested dicts)."""

    def __init__(self, data):
        self.path = data["source_path"]
        self.format_version = data["format_version"]
        self.created_utc = data["created_utc"]
        self.damper_serial = data["damper_serial"]
        self.rig = data["rig"]
        self.profile = data["profile"]
        self.metadata = data["metadata"]
        self.experiments = {e["label"]: Experiment(e) for e in data["experiments"]}

    def __getitem__(self, label):
        try:
            return self.experiments[label]
        except KeyError:
            raise KeyError(f"session {self.path}: no experiment {label!r} (it has {', '.join(self.experiments)})") from None

    def __iter__(self):
        return iter(self.experiments.values())

    def __len__(self):
        return len(self.experiments)

    def __fspath__(self):
        if not self.path:
            raise TypeError("the session has no file")
        return self.path

    def summary(self):
        """One row per experiment: label, kind, frequency, amplitude, static position, sample rate, samples."""
        keys = ["label", "kind", "status", "frequency", "amplitude", "static_position", "sample_rate", "periods",
                "drop_mass", "impact_velocity"]
        columns = {k: [e.metadata[k] for e in self] for k in keys}
        columns["samples"] = [len(e.time) for e in self]
        return table(columns, "label")

    def _repr_html_(self):
        s = self.summary()
        body = s.to_html() if has_pandas() else html(s)
        return f"<p>strut session {self.path} (serial {self.damper_serial}, rig {self.rig})</p>{body}"

    def __repr__(self):
        return f"<strut.Session {self.path}: {len(self)} experiments, serial {self.damper_serial!r}>"


def read_session(path):
    """Reads and validates a session file (HDF5); strut.SessionError names the file and what is wrong."""
    return Session(_strut.read_session(os.fspath(path)))
