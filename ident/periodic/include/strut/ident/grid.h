// The periodic grid and its phases: difference schemes and their stencils on equidistant or
// recorded-sample phases, period-synchronous sampling of a record, and the maps from a grid to the
// data's phases (interpolation, least-squares products).
#pragma once

#include <Eigen/Dense>
#include <Eigen/Sparse>
#include <array>
#include <span>
#include <string_view>
#include <vector>

namespace strut::ident {

enum class Scheme {
  kBackward2,  //!< second-order backward differences (paper eqs. 8, 9), the default
  kCentral2,   //!< second-order central differences
  kCentral4,   //!< fourth-order central differences
  kSpectral,   //!< Fourier collocation (harmonic balance in the time domain); dense, small n
};
std::string_view ToString(Scheme s);
Scheme ParseScheme(std::string_view text);  //!< backward2, central2, central4, spectral

//! Difference operators on the periodic grid in cyclic time tau (period 1):
//! dx/dtau at point mu ~ sum_k First(mu, k) x[mu + k], likewise Second for d2x/dtau2. On an
//! equidistant grid the weights are the same at every point (`first`, `second`); on any other
//! (`PeriodicInput::phases`) each point has its own, the Lagrange weights of the scheme's offsets at
//! the actual phases (backward2: first derivative from offsets -2..0, second from -3..0; central2
//! -1..1; central4 -2..2), `first_at` and `second_at` point-major.
struct Stencil {
  int kmin = 0, kmax = 0;
  std::vector<double> first, second;
  std::vector<double> first_at, second_at;  //!< n x (kmax - kmin + 1); empty when equidistant
  double First(int mu, int k) const {
    return first_at.empty() ? first[k - kmin] : first_at[static_cast<std::size_t>(mu) * (kmax - kmin + 1) + (k - kmin)];
  }
  double Second(int mu, int k) const {
    return second_at.empty() ? second[k - kmin]
                             : second_at[static_cast<std::size_t>(mu) * (kmax - kmin + 1) + (k - kmin)];
  }
  bool equidistant() const { return first_at.empty(); }
  static Stencil For(Scheme scheme, int n);
  //! At the given phases (strictly increasing in [0, 1); empty: equidistant on n = 0 points is not
  //! allowed, use For(scheme, n)). Throws std::invalid_argument for the spectral scheme.
  static Stencil For(Scheme scheme, const std::vector<double>& phases);
};

//! The record at grid time t_mu of every period: an n x periods matrix, linearly interpolated from
//! `periods` whole recorded periods starting at sample 0 (the sample after the last one is the
//! first one). Throws std::invalid_argument when the record is too short or the sizes are bad.
Eigen::MatrixXd PeriodSynchronousSamples(std::span<const double> samples, double sample_rate, double frequency,
                                         long periods, int n);

//! Periodic cubic (Catmull-Rom) resampling of every row (one period on equidistant points starting
//! at phase 0) onto `points` equidistant points: the coarse-grid start's interpolation both ways.
Eigen::MatrixXd PeriodicResample(const Eigen::MatrixXd& rows, int points);

//! Periodic cubic (4-point Lagrange) interpolation from the n grid points at `grid` phases (empty:
//! mu / n) to any phases in [0, 1): for each target the four grid points around it (wrapped) and
//! their weights. A target on a grid point gets that point's value exactly.
struct PhaseInterpolation {
  std::vector<std::array<int, 4>> taps;
  std::vector<std::array<double, 4>> weights;
  static PhaseInterpolation Cubic(const std::vector<double>& grid, int n, std::span<const double> targets);
  //! Every column of `grid` (n rows) at the targets (a targets x columns matrix).
  Eigen::MatrixXd Columns(const Eigen::MatrixXd& grid) const;
  //! Every row of `rows` (n columns) at the targets.
  Eigen::MatrixXd Rows(const Eigen::MatrixXd& rows) const;
};

//! Least-squares products over the targets of grid functions mapped there, at the grid's size: with
//! P the interpolation (targets x n), J = P G gives J^T J = G^T A G and J^T r = G^T P^T r where
//! A = P^T P = Q^T L L^T Q (sparse Cholesky, Q its fill-reducing order). So Columns(G) = L^T Q G
//! (n rows) stands for J and Vector(r) = L^-1 Q P^T r for r in every product: a thinned grid of
//! 490 points serves the 5000 samples of experiment a. Needs every grid point to carry weight
//! (A positive definite), as on a grid of sample phases.
class PhaseProducts {
 public:
  PhaseProducts(const PhaseInterpolation& map, int n);
  Eigen::MatrixXd Columns(const Eigen::MatrixXd& grid) const;
  Eigen::VectorXd Vector(const Eigen::VectorXd& at_targets) const;
  //! P^T P g from a column of Columns(g): the products' weights back on the grid.
  Eigen::VectorXd GridWeights(const Eigen::VectorXd& column) const;

 private:
  Eigen::SparseMatrix<double> transpose_map_;  // P^T
  Eigen::SparseMatrix<double> lower_;          // L
  Eigen::SparseMatrix<double, Eigen::RowMajor> upper_ordered_;  // L^T Q, one product for Columns
  Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic> order_;  // Q
};

}  // namespace strut::ident
