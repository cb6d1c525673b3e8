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
};

//! Every term a composition may name, in evaluation order.
const std::vector<TermEntry>& Catalogue();

//! The terms of a base model ("1dof", "2dof"); empty for an unknown base.
const std::vector<std::string>& BaseTerms(std::string_view base);

}  // namespace strut::ident
