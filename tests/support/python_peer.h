// A real peer program for the session files: python3 with h5py and numpy (test_support.cpp).
#pragma once

#include <string>

#include "test_support.h"

namespace strut::test {

//! A python3 that imports h5py and numpy ("python3" or "/usr/bin/python3"), or empty: the one on
//! PATH may be a bare pyenv.
std::string PythonWithH5py();

//! Runs `script` (written to dir/script.py) with `python` and `arguments` (shell-quoted by the
//! caller); its exit code, -1 when it did not exit normally.
int RunPython(const std::string& python, const TempDir& dir, const std::string& script, const std::string& arguments);

}  // namespace strut::test
