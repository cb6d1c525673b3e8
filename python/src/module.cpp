// strut._strut: the extension module of the Python package strut (docs/python.md). The
// pure-Python layer (python/strut/) is what users import; this module holds the C++ side.
#include <CLI/CLI.hpp>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include "bindings.h"

namespace strut::python {
namespace {

void SetLogLevel(const std::string& level) {
  const spdlog::level::level_enum l = spdlog::level::from_str(level);
  if (l == spdlog::level::off && level != "off")
    throw std::invalid_argument("log level '" + level + "': give trace, debug, info, warning, error or off");
  spdlog::set_level(l);
}

}  // namespace
}  // namespace strut::python

PYBIND11_MODULE(_strut, m) {
  using namespace strut;
  using namespace strut::python;
  m.doc() = "strut's C++ side: sessions, fits, discovery, QC, drop prediction and the simulated rig.";
  // As the CLI: logs go to stderr, with the CLI's pattern; warnings and errors only unless asked
  // (strut.set_log_level("info") shows what the CLI shows).
  if (!spdlog::get("strut")) spdlog::set_default_logger(spdlog::stderr_color_mt("strut"));
  spdlog::set_pattern("%^[%l]%$ %v");
  spdlog::set_level(spdlog::level::warn);
  m.def("set_log_level", &SetLogLevel, py::arg("level"),
        "The level of strut's log on stderr: trace, debug, info (the CLI's default), warning (the default here), "
        "error or off.");

  // Errors keep the message the CLI prints: strut.Error for strut's own errors, strut.SessionError
  // for a bad session file, strut.OptionError for a refused option, ValueError for bad input.
  static py::exception<std::runtime_error> error(m, "Error", PyExc_RuntimeError);
  static py::exception<daq::SessionError> session_error(m, "SessionError", error.ptr());
  static py::exception<OptionError> option_error(m, "OptionError", PyExc_ValueError);
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const py::builtin_exception&) {
      throw;  // TypeError and the like, pybind11's own translator
    } catch (const py::error_already_set&) {
      throw;
    } catch (const daq::SessionError& e) {
      session_error(e.what());
    } catch (const OptionError& e) {
      option_error(e.what());
    } catch (const std::invalid_argument& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    } catch (const std::exception& e) {
      error(e.what());
    }
  });

  AddSessionFunctions(m);
  AddCommands(m);
}
