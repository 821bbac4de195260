#include "cvode_integrator.h"

#include <vector>

#include "pneuma/core/error.h"

namespace pneuma::physiology::detail {
namespace {

// CVODE prints to stderr by default; keep its message for our own one-line error instead.
void keep_message(int, const char*, const char* function, char* message, void* self) {
  *static_cast<std::string*>(self) = std::string(function) + ": " + message;
}

}  // namespace

CvodeIntegrator::CvodeIntegrator(int size, CVRhsFn rhs, void* user_data, const SolverOptions& options) : size_(size) {
  if (SUNContext_Create(nullptr, &context_) != 0) throw Error(ExitCode::failure, "CVODE: cannot create a context");
  state_ = N_VNew_Serial(size, context_);
  matrix_ = SUNDenseMatrix(size, size, context_);
  solver_ = SUNLinSol_Dense(state_, matrix_, context_);
  cvode_ = CVodeCreate(CV_BDF, context_);
  if (!state_ || !matrix_ || !solver_ || !cvode_) throw Error(ExitCode::failure, "CVODE: out of memory");
  check(CVodeSetErrHandlerFn(cvode_, keep_message, &last_error_), "CVodeSetErrHandlerFn");
  N_VConst(0.0, state_);
  check(CVodeInit(cvode_, rhs, 0.0, state_), "CVodeInit");
  check(CVodeSStolerances(cvode_, options.relative_tolerance, options.absolute_tolerance_m3), "CVodeSStolerances");
  check(CVodeSetLinearSolver(cvode_, solver_, matrix_), "CVodeSetLinearSolver");
  check(CVodeSetUserData(cvode_, user_data), "CVodeSetUserData");
  check(CVodeSetMaxNumSteps(cvode_, 100000), "CVodeSetMaxNumSteps");
  if (options.max_step_s > 0.0) check(CVodeSetMaxStep(cvode_, options.max_step_s), "CVodeSetMaxStep");
}

CvodeIntegrator::~CvodeIntegrator() {
  if (cvode_) CVodeFree(&cvode_);
  if (solver_) SUNLinSolFree(solver_);
  if (matrix_) SUNMatDestroy(matrix_);
  if (state_) N_VDestroy(state_);
  if (context_) SUNContext_Free(&context_);
}

void CvodeIntegrator::check(int flag, const char* call) const {
  if (flag < 0) {
    throw Error(ExitCode::failure, std::string("CVODE failed in ") + call + " (" + CVodeGetReturnFlagName(flag) + ")" +
                                       (last_error_.empty() ? "" : ": " + last_error_));
  }
}

void CvodeIntegrator::restart(double t0, const double* y0, double stop_time) {
  double* y = N_VGetArrayPointer(state_);
  for (int i = 0; i < size_; ++i) y[i] = y0[i];
  // CVodeReInit zeroes CVODE's counters; keep the running totals here.
  long steps = 0, evaluations = 0;
  CVodeGetNumSteps(cvode_, &steps);
  CVodeGetNumRhsEvals(cvode_, &evaluations);
  totals_.steps += steps;
  totals_.rhs_evaluations += evaluations;
  check(CVodeReInit(cvode_, t0, state_), "CVodeReInit");
  check(CVodeSetStopTime(cvode_, stop_time), "CVodeSetStopTime");
  ++restarts_;
}

void CvodeIntegrator::set_roots(int count, CVRootFn g, const int* directions) {
  if (count == 0 && root_count_ == 0) return;
  check(CVodeRootInit(cvode_, count, count > 0 ? g : nullptr), "CVodeRootInit");
  root_count_ = count;
  if (count > 0) {
    std::vector<int> d(directions, directions + count);
    check(CVodeSetRootDirection(cvode_, d.data()), "CVodeSetRootDirection");
    check(CVodeSetNoInactiveRootWarn(cvode_), "CVodeSetNoInactiveRootWarn");
  }
}

double CvodeIntegrator::advance(double t, double* y, int* root) {
  double reached = 0.0;
  const int flag = CVode(cvode_, t, state_, &reached, CV_NORMAL);
  check(flag, "CVode");
  const double* s = N_VGetArrayPointer(state_);
  for (int i = 0; i < size_; ++i) y[i] = s[i];
  if (root) *root = -1;
  if (flag == CV_ROOT_RETURN && root) {
    std::vector<int> found(static_cast<std::size_t>(root_count_));
    check(CVodeGetRootInfo(cvode_, found.data()), "CVodeGetRootInfo");
    for (int i = 0; i < root_count_; ++i) {
      if (found[static_cast<std::size_t>(i)] != 0) {
        *root = i;
        break;
      }
    }
  }
  return reached;
}

SolverStats CvodeIntegrator::stats() const {
  SolverStats s = totals_;
  long steps = 0, evaluations = 0;
  CVodeGetNumSteps(cvode_, &steps);
  CVodeGetNumRhsEvals(cvode_, &evaluations);
  s.steps += steps;
  s.rhs_evaluations += evaluations;
  s.restarts = restarts_;
  return s;
}

}  // namespace pneuma::physiology::detail
