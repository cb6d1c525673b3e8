"""strut from Python: sessions as numpy arrays, fits as objects (docs/python.md).

Every function calls what the strut command of the same name calls, and takes the command's long
options as keyword arguments with the same names ('-' as '_') and the same defaults::

    import strut
    session = strut.sim_matrix(draw=12, output="unit12.h5")    # strut sim matrix --draw 12 -o unit12.h5
    fit = strut.identify("unit12.h5", model="2dof")              # strut identify unit12.h5 --model 2dof
    fit.parameters                                               # a pandas DataFrame (dicts without pandas)
"""
from ._strut import Error, OptionError, SessionError, set_log_level
from .commands import discover, identify, options, predict_drop, qc, sim_drop, sim_matrix
from .results import Discovery, DropPrediction, Fit, QcDecision
from .session import Experiment, Session, read_session
from .tables import has_pandas

__all__ = [
    "Error", "OptionError", "SessionError", "set_log_level",
    "read_session", "Session", "Experiment",
    "identify", "discover", "qc", "predict_drop", "sim_matrix", "sim_drop", "options",
    "Fit", "Discovery", "QcDecision", "DropPrediction", "has_pandas",
]
