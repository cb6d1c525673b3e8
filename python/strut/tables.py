"""Tables as pandas DataFrames where pandas is installed, else as dicts of numpy arrays."""
import os

import numpy as np

try:  # pandas is optional (python3-pandas); STRUT_NO_PANDAS=1 shows what a machine without it gets
    if os.environ.get("STRUT_NO_PANDAS"):
        raise ImportError("STRUT_NO_PANDAS is set")
    import pandas as _pd
except ImportError:
    _pd = None


def has_pandas():
    """True when tables are pandas DataFrames."""
    return _pd is not None


def table(columns, index=None):
    """A DataFrame of `columns` (name -> sequence), indexed by the column `index`; without pandas the
    same columns as a dict of numpy arrays."""
    columns = {name: np.asarray(values) for name, values in columns.items()}
    if _pd is None:
        return columns
    frame = _pd.DataFrame(columns)
    return frame.set_index(index) if index else frame


def rows_table(rows, index=None):
    """A table of records (a list of dicts with the same keys)."""
    if not rows:
        return table({})
    return table({key: [row[key] for row in rows] for key in rows[0]}, index)


def html(columns):
    """An HTML table of a columns dict, for _repr_html_ without pandas."""
    import html as _html
    names = list(columns)
    head = "".join(f"<th>{_html.escape(str(n))}</th>" for n in names)
    length = len(next(iter(columns.values()))) if columns else 0
    body = "".join("<tr>" + "".join(f"<td>{_html.escape(str(columns[n][i]))}</td>" for n in names) + "</tr>"
                   for i in range(length))
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"
