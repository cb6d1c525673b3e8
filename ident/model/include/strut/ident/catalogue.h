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

//! One function of the empirical discrepancy's library (the `discrepancy` term, docs/discovery.md):
//! its coefficient theta<index> is dimensionless, 0 absent.
struct DiscrepancyFunction {
  int index = 0;          //!< paper-style index of its coefficient (70..99)
  std::string name;       //!< e.g. "damping-direction"
  std::string shape;      //!< the function, in symbols and words
  std::string resembles;  //!< the catalogue term whose signature it shares ("" none)
  double typical = 0.0;   //!< size of a meaningful coefficient (the prior's sd under --model ...+discrepancy)
  //! theta<shape_index>: a parameter of the function's shape (an exponent, a contact position),
  //! estimated where the function is and fixed where it is not (0: none).
  int shape_index = 0;
  //! The shape values a start tries: the one whose Gauss-Newton step leaves the least residual.
  std::vector<double> shape_grid;
  //! The catalogue term whose signature the function shares with a negative coefficient, where that
  //! is another than `resembles` ("" the same).
  std::string resembles_when_negative;
};

//! The discrepancy's whole library, in evaluation order (a model holds those its terms allow).
const std::vector<DiscrepancyFunction>& DiscrepancyLibrary();

//! The terms of a base model ("1dof", "2dof", "linear-oscillator"); empty for an unknown base.
const std::vector<std::string>& BaseTerms(std::string_view base);

}  // namespace strut::ident
