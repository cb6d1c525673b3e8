// The term catalogue (private to ident): names, factories, and the bases built from them.
#pragma once

#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "strut/ident/model.h"

namespace strut::ident {

struct TermEntry {
  std::string name;
  std::shared_ptr<Term> (*make)();
  std::string replaces;     //!< a term this one takes the place of ("" if none)
  std::string description;
  //! Where its absence shows in the residuals of a fit without it (the located-mismatch feature
  //! discovery scores it against; docs/discovery.md lists them), and that evidence in words.
  std::string locus;
  std::string signature;
};

//! Every term a composition may name, in evaluation order.
const std::vector<TermEntry>& Catalogue();

//! The terms of a base model ("1dof", "2dof", "linear-oscillator"); empty for an unknown base.
const std::vector<std::string>& BaseTerms(std::string_view base);

}  // namespace strut::ident
