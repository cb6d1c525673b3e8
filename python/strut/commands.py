"""The strut commands from Python. Each takes the command's long options as keyword arguments
(`--estimate-input on` is estimate_input="on", a flag is True/False, a repeatable option a list) and
parses them with the CLI's own option definitions: the same names, defaults, ranges and messages."""
import os
import tempfile

from . import _strut
from .results import Discovery, DropPrediction, Fit, QcDecision
from .session import Session


def _paths(sessions):
    if len(sessions) == 1 and isinstance(sessions[0], (list, tuple)):
        sessions = sessions[0]
    if not sessions:
        raise TypeError("give at least one session file")
    return [os.fspath(s) for s in sessions]


def identify(*sessions, **options):
    """strut identify SESSION... [--OPTION VALUE...]: the multi-experiment fit; returns a Fit (whatever
    its verdict: look at fit.verdict). json=/report= write the CLI's files too."""
    return Fit(_strut.identify(_paths(sessions), options))


def discover(*sessions, **options):
    """strut discover SESSION... [--OPTION VALUE...]: the physics the model leaves out; returns a Discovery."""
    return Discovery(_strut.discover(_paths(sessions), options))


def qc(session, **options):
    """strut qc SESSION --reference REF [...]: PASS, FAIL or UNDECIDED; returns a QcDecision. Errors raise
    (where the CLI says UNDECIDED with exit code 2)."""
    return QcDecision(_strut.qc(os.fspath(session), options))


def predict_drop(**options):
    """strut predict drop --fit FIT.json [...]: fit= takes a Fit too. Returns a DropPrediction."""
    fit = options.get("fit")
    if isinstance(fit, Fit):
        with tempfile.TemporaryDirectory() as folder:
            path = os.path.join(folder, "fit.json")
            fit.write_json(path)
            return DropPrediction(_strut.predict_drop({**options, "fit": path}))
    return DropPrediction(_strut.predict_drop(options))


def sim_matrix(**options):
    """strut sim matrix [--draw SEED ...] -o SESSION.h5: records a test matrix on the simulated rig
    (output= is required, as -o is); returns the Session it wrote."""
    return Session(_strut.sim_matrix(options))


def sim_drop(**options):
    """strut sim drop [...] -o DROP.h5: a drop test on the simulated rig; returns the Session it wrote."""
    return Session(_strut.sim_drop(options))


def options(command):
    """The keyword arguments of a command ("identify", "discover", "qc", "predict drop", "sim matrix",
    "sim drop"): keyword -> option, default (as --help shows it), flag, required, description."""
    return _strut.options(command.replace("_", " "))
