// What a unit is compared with (docs/qc.md): either a golden unit's fit (the JSON `strut identify`
// writes), whose quantities become the nominal values with the default tolerance bands, or a
// reference file of nominal values with bands (TOML or JSON).
#pragma once

#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace strut::qc {

//! A mistake in a reference file; the message names the file and the item (and line for TOML).
class ReferenceError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

//! The tolerance of one quantity: accepted values lie in [lower, upper].
struct Band {
  std::string name;
  double nominal = 0.0;
  double lower = 0.0;
  double upper = 0.0;
};

//! Default bands around a golden unit's values: relative (charge, gas volume, friction, orifice,
//! viscous, heat transfer) or absolute (the sensor offsets). docs/qc.md gives the reasoning.
struct DefaultBand {
  std::string name;
  bool relative = true;
  double below = 0.0;  //!< relative: lower = nominal * (1 - below); absolute: lower = nominal - below
  double above = 0.0;  //!< relative: upper = nominal * (1 + above); absolute: upper = nominal + above
};
const std::vector<DefaultBand>& DefaultBands();

struct Reference {
  std::string source;             //!< the file
  std::string kind;               //!< "golden-fit" or "nominal-file"
  std::string model;              //!< composition the QC fit uses ("" = the QC default)
  std::vector<Band> bands;
  const Band* find(std::string_view name) const;
};

//! The reference a golden unit's identify JSON gives: its quantities as nominal values with
//! DefaultBands(). `tolerance_overrides` (bands from a file) replace the defaults by name.
//! Throws ReferenceError naming the file when the JSON lacks what a fit has, its model is not a
//! damper, or its verdict is not "at-noise-floor".
Reference ReferenceFromFitJson(const std::string& json_text, const std::string& source);

//! A reference file of nominal values with bands, TOML or JSON (the format is told by the first
//! non-blank character: '{' is JSON). Throws ReferenceError naming the file and line or key.
Reference ParseNominalFile(std::string_view text, const std::string& source);

//! Reads `path`: an identify JSON (it has "parameters" and "model") or a nominal file.
Reference ReadReference(const std::string& path);

}  // namespace strut::qc
