#include "ida_run.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cstdlib>
#include <fmt/format.h>
#include <new>
#include <stdexcept>

#include "strut/sim/transient_predictor.h"

namespace strut::sim::detail {
namespace {

std::string FlagName(int flag) {
  char* name = IDAGetReturnFlagName(flag);  // malloc'ed by SUNDIALS
  std::string s = name ? name : fmt::format("IDA flag {}", flag);
  std::free(name);
  return s;
}

int ResidualCallback(double t, N_Vector y, N_Vector yp, N_Vector r, void* user) {
  auto* data = static_cast<CallbackData*>(user);
  const int n = data->system->size();
  try {
    const std::span<const double> ys(N_VGetArrayPointer(y), n), yps(N_VGetArrayPointer(yp), n);
    const InputSample u = data->system->Input(t, yps);
    if (!std::isfinite(u.value) || !std::isfinite(u.rate) || !std::isfinite(u.accel)) {
      data->failure = fmt::format("the input is not finite at t = {:.9g} s (u = {}, u' = {}, u'' = {})", t, u.value,
                                  u.rate, u.accel);
      return -1;
    }
    std::span<double> rs(N_VGetArrayPointer(r), n);
    data->system->Residual(t, ys, yps, rs);
    for (double v : rs)
      if (!std::isfinite(v)) return 1;  // recoverable: IDA retries with a smaller step
    return 0;
  } catch (...) {  // no exception may cross IDAS: IdaRun::Fail rethrows it once IDAS has returned
    data->error = std::current_exception();
    return -1;
  }
}

int JacobianCallback(double t, double cj, N_Vector y, N_Vector yp, N_Vector, SUNMatrix jac, void* user, N_Vector,
                     N_Vector, N_Vector) {
  auto* data = static_cast<CallbackData*>(user);
  const int n = data->system->size();
  try {
    const Eigen::MatrixXd j = data->system->Jacobian(t, std::span<const double>(N_VGetArrayPointer(y), n),
                                                     std::span<const double>(N_VGetArrayPointer(yp), n), cj);
    if (!j.allFinite()) return 1;
    for (int c = 0; c < n; ++c) std::copy(j.col(c).data(), j.col(c).data() + n, SUNDenseMatrix_Column(jac, c));
    return 0;
  } catch (...) {  // no exception may cross IDAS: IdaRun::Fail rethrows it once IDAS has returned
    data->error = std::current_exception();
    return -1;
  }
}

int SensitivityCallback(int ns, double t, N_Vector y, N_Vector yp, N_Vector, N_Vector* ys, N_Vector* yps,
                        N_Vector* rs, void* user, N_Vector, N_Vector, N_Vector) {
  auto* data = static_cast<CallbackData*>(user);
  const SensitivitySetup& setup = *data->sensitivities;
  const int n = data->system->size();
  try {
    Eigen::MatrixXd s(n, ns), sp(n, ns);
    for (int k = 0; k < ns; ++k) {
      s.col(k) = Eigen::Map<const Eigen::VectorXd>(N_VGetArrayPointer(ys[k]), n);
      sp.col(k) = Eigen::Map<const Eigen::VectorXd>(N_VGetArrayPointer(yps[k]), n);
    }
    const Eigen::MatrixXd r = SensitivityResiduals(
        data->system->model(), setup.theta, *setup.load, setup.parameters, t,
        std::span<const double>(N_VGetArrayPointer(y), n), std::span<const double>(N_VGetArrayPointer(yp), n), s, sp);
    if (!r.allFinite()) return 1;
    for (int k = 0; k < ns; ++k) Eigen::Map<Eigen::VectorXd>(N_VGetArrayPointer(rs[k]), n) = r.col(k);
    return 0;
  } catch (...) {  // no exception may cross IDAS: IdaRun::Fail rethrows it once IDAS has returned
    data->error = std::current_exception();
    return -1;
  }
}

void ErrorHandler(int code, const char* module, const char* function, char* message, void* user) {
  // Kept for the exception text instead of printed to stderr; warnings only go to the debug log.
  auto& text = static_cast<CallbackData*>(user)->ida_message;
  text = fmt::format("{}/{}: {}", module ? module : "IDA", function ? function : "?", message ? message : "");
  if (code > 0) spdlog::debug("transient: {}", text);
}

}  // namespace

SundialsContext::SundialsContext() {
  if (SUNContext_Create(nullptr, &ctx) != 0) throw std::runtime_error("transient: SUNContext_Create failed");
}
SundialsContext::~SundialsContext() { SUNContext_Free(&ctx); }

IdaRun::IdaRun(SUNContext ctx, const DaeSystem& system, const TransientOptions& options, std::span<const double> y0,
               std::span<const double> yp0, const SensitivitySetup* sensitivities)
    : n_(system.size()), max_steps_(options.max_steps) {
  data_.system = &system;
  data_.sensitivities = sensitivities;
  y_ = N_VNew_Serial(n_, ctx);
  yp_ = N_VNew_Serial(n_, ctx);
  id_ = N_VNew_Serial(n_, ctx);
  atol_ = N_VNew_Serial(n_, ctx);
  matrix_ = SUNDenseMatrix(n_, n_, ctx);
  mem_ = IDACreate(ctx);
  if (!y_ || !yp_ || !id_ || !atol_ || !matrix_ || !mem_) throw std::bad_alloc();
  solver_ = SUNLinSol_Dense(y_, matrix_, ctx);
  if (!solver_) throw std::bad_alloc();
  const auto differential = system.differential();
  const Eigen::VectorXd scales = system.scales();
  for (int j = 0; j < n_; ++j) {
    NV_Ith_S(y_, j) = y0[j];
    NV_Ith_S(yp_, j) = yp0[j];
    NV_Ith_S(id_, j) = differential[j] ? 1.0 : 0.0;
    NV_Ith_S(atol_, j) = options.atol_factor * scales[j];
  }
  Check(IDASetErrHandlerFn(mem_, ErrorHandler, &data_), "IDASetErrHandlerFn");
  Check(IDAInit(mem_, ResidualCallback, 0.0, y_, yp_), "IDAInit");
  Check(IDASVtolerances(mem_, options.rtol, atol_), "IDASVtolerances");
  Check(IDASetUserData(mem_, &data_), "IDASetUserData");
  Check(IDASetLinearSolver(mem_, solver_, matrix_), "IDASetLinearSolver");
  Check(IDASetJacFn(mem_, JacobianCallback), "IDASetJacFn");
  Check(IDASetId(mem_, id_), "IDASetId");
  Check(IDASetMaxOrd(mem_, options.max_order), "IDASetMaxOrd");
  if (options.max_step > 0) Check(IDASetMaxStep(mem_, options.max_step), "IDASetMaxStep");
  if (!sensitivities) return;
  const Eigen::MatrixXd& s0 = sensitivities->start;
  ns_ = static_cast<int>(s0.cols());
  if (s0.rows() != n_ || static_cast<int>(sensitivities->parameters.size()) != ns_ ||
      static_cast<int>(sensitivities->pbar.size()) != ns_ || !sensitivities->load)
    throw std::invalid_argument("transient: sensitivity set-up of the wrong size");
  ys_ = N_VCloneVectorArray(ns_, y_);
  yps_ = N_VCloneVectorArray(ns_, y_);
  if (!ys_ || !yps_) throw std::bad_alloc();
  for (int k = 0; k < ns_; ++k)
    for (int j = 0; j < n_; ++j) {
      NV_Ith_S(ys_[k], j) = s0(j, k);
      NV_Ith_S(yps_[k], j) = 0.0;  // IDACalcIC completes them
    }
  Check(IDASensInit(mem_, ns_, sensitivities->staggered ? IDA_STAGGERED : IDA_SIMULTANEOUS, SensitivityCallback, ys_,
                    yps_),
        "IDASensInit");
  // p is not needed (the sensitivity residual is exact); pbar scales the sensitivity tolerances.
  Check(IDASetSensParams(mem_, nullptr, const_cast<double*>(sensitivities->pbar.data()), nullptr), "IDASetSensParams");
  Check(IDASensEEtolerances(mem_), "IDASensEEtolerances");
  Check(IDASetSensErrCon(mem_, sensitivities->error_control ? SUNTRUE : SUNFALSE), "IDASetSensErrCon");
}

IdaRun::~IdaRun() {
  IDAFree(&mem_);
  if (ys_) N_VDestroyVectorArray(ys_, ns_);
  if (yps_) N_VDestroyVectorArray(yps_, ns_);
  if (solver_) SUNLinSolFree(solver_);
  if (matrix_) SUNMatDestroy(matrix_);
  for (N_Vector v : {y_, yp_, id_, atol_})
    if (v) N_VDestroy(v);
}

void IdaRun::ConsistentStart(double tout1) {
  Check(IDACalcIC(mem_, IDA_YA_YDP_INIT, tout1), "IDACalcIC (consistent initial conditions)");
  Check(IDAGetConsistentIC(mem_, y_, yp_), "IDAGetConsistentIC");
  if (ns_ > 0) Check(IDAGetSensConsistentIC(mem_, ys_, yps_), "IDAGetSensConsistentIC");
  t_ = 0.0;
}

void IdaRun::AdvanceTo(double tout, double tstop) {
  const long remaining = max_steps_ - steps();
  if (remaining <= 0) BudgetExceeded();
  Check(IDASetMaxNumSteps(mem_, remaining), "IDASetMaxNumSteps");
  if (tstop != tstop_) {
    Check(IDASetStopTime(mem_, tstop), "IDASetStopTime");
    tstop_ = tstop;
  }
  double reached = t_;
  const int flag = IDASolve(mem_, tout, &reached, y_, yp_, IDA_NORMAL);
  IDAGetCurrentTime(mem_, &t_);
  if (flag < 0) {
    if (flag == IDA_TOO_MUCH_WORK) BudgetExceeded();
    Fail(flag, fmt::format("IDASolve towards t = {:.9g} s", tout));
  }
  t_ = reached;
  if (ns_ > 0) Check(IDAGetSens(mem_, &reached, ys_), "IDAGetSens");
}

long IdaRun::Counter(int (*get)(void*, long*)) const {
  long value = 0;
  get(mem_, &value);
  return value;
}

void IdaRun::Check(int flag, const char* what) {
  if (flag < 0) Fail(flag, what);
}

void IdaRun::BudgetExceeded() const {
  throw TransientError(fmt::format("transient: step budget of {} internal steps used up at t = {:.9g} s with {} "
                                   "(raise TransientOptions::max_steps or loosen rtol)",
                                   max_steps_, t_, FlagName(IDA_TOO_MUCH_WORK)),
                       t_, IDA_TOO_MUCH_WORK);
}

void IdaRun::Fail(int flag, const std::string& what) {
  if (data_.error) std::rethrow_exception(data_.error);
  const std::string detail = !data_.failure.empty() ? data_.failure : data_.ida_message;
  throw TransientError(fmt::format("transient: {} failed at t = {:.9g} s with {}{}{}", what, t_, FlagName(flag),
                                   detail.empty() ? "" : ": ", detail),
                       t_, flag);
}

double PeriodChange(const Eigen::MatrixXd& current, const Eigen::MatrixXd& previous, const Eigen::VectorXd& scale,
                    double relative_floor) {
  const Eigen::VectorXd peak = current.cwiseAbs().rowwise().maxCoeff();
  const Eigen::VectorXd w = scale.cwiseMax(relative_floor * peak);
  return ((current - previous).cwiseAbs().array().colwise() / w.array()).maxCoeff();
}

bool PeriodConvergence::Add(double change, double tol) {
  change_ = change;
  changes_.push_back(change);
  const int window = std::min<int>(4, static_cast<int>(changes_.size()) - 1);
  const double rho = window > 0 && changes_[changes_.size() - 1 - window] > 0
                         ? std::pow(change / changes_[changes_.size() - 1 - window], 1.0 / window)
                         : INFINITY;
  estimate_ = rho < 1.0 ? change * rho / (1.0 - rho) : change;
  return window > 0 && change <= tol && estimate_ <= tol;
}

}  // namespace strut::sim::detail
