// The pieces of the extension module strut._strut (module.cpp holds its definition).
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <stdexcept>
#include <string>
#include <vector>

#include "strut/daq/session.h"

namespace strut::python {

namespace py = pybind11;

//! A command line the CLI's option definitions refuse (CLI::ParseError's message): strut.OptionError.
class OptionError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

//! A copy of `values` as a 1-d float64 numpy array.
py::array_t<double> Array(const std::vector<double>& values);

//! A session as plain Python data: a dict of its attributes, "metadata" (the extra root groups as
//! nested dicts) and "experiments" (a list of dicts, each with "time" and "channels" as numpy
//! arrays). The pure-Python layer (strut/session.py) wraps it.
py::dict SessionToPython(const daq::Session& session);

//! read_session(path), sim_matrix(kwargs), ...: the module's functions over sessions.
void AddSessionFunctions(py::module_& m);
//! identify, discover, qc, predict_drop and their results.
void AddCommands(py::module_& m);

}  // namespace strut::python
