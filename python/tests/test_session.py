"""Sessions read into numpy arrays through daq's reader, against h5py reading the same file."""
import h5py
import numpy as np
import pytest

import strut


def test_arrays_equal_what_h5py_reads(lab):
    path = lab / "unit12.h5"
    session = strut.read_session(path)
    with h5py.File(path, "r") as f:
        labels = list(f["experiments"].keys())
        assert sorted(session.experiments) == sorted(labels)
        for label in labels:
            g = f["experiments"][label]
            e = session[label]
            assert e.time.dtype == np.float64
            assert np.array_equal(e.time, g["time"][()])
            channels = [name for name in g.keys() if name != "time"]
            assert sorted(e.channels) == sorted(channels)
            for name in channels:
                assert np.array_equal(e[name], g[name][()]), (label, name)
                units = g[name].attrs["units"]
                assert e.units[name] == (units.decode() if isinstance(units, bytes) else units)
            for attribute in ("frequency", "amplitude", "static_position", "sample_rate"):
                assert getattr(e, attribute) == g.attrs[attribute], (label, attribute)
        serial = f.attrs["damper_serial"]
        assert session.damper_serial == (serial.decode() if isinstance(serial, bytes) else serial)
        # A simulated session records its truth: an extra root group, as nested dicts.
        assert "truth" in session.metadata and "truth" in f


def test_a_file_that_is_not_a_session_raises_naming_the_file(tmp_path):
    bad = tmp_path / "not-a-session.h5"
    bad.write_bytes(b"this is not HDF5\n" * 10)
    with pytest.raises(strut.SessionError) as raised:
        strut.read_session(bad)
    assert str(bad) in str(raised.value)
    # The same error from a command that reads it, as the CLI reports it.
    with pytest.raises(strut.SessionError) as fitting:
        strut.identify(bad)
    assert str(bad) in str(fitting.value)


def test_a_truncated_session_raises_naming_the_file(lab, tmp_path):
    whole = (lab / "unit12.h5").read_bytes()
    cut = tmp_path / "cut.h5"
    cut.write_bytes(whole[: len(whole) // 2])
    with pytest.raises(strut.SessionError) as raised:
        strut.read_session(cut)
    assert str(cut) in str(raised.value)


def test_a_missing_file_raises_naming_it(tmp_path):
    with pytest.raises(strut.Error) as raised:
        strut.read_session(tmp_path / "no-such.h5")
    assert "no-such.h5" in str(raised.value)


def test_experiment_frame_holds_time_and_channels(lab):
    e = next(iter(strut.read_session(lab / "unit12.h5")))
    frame = e.to_frame()
    assert list(frame["time"]) == list(e.time)
    assert set(e.channels) <= set(frame.keys() if isinstance(frame, dict) else frame.columns)
