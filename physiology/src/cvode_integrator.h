#pragma once
// RAII ownership of one CVODE (BDF, dense Newton) integrator: context, vector, matrix, solver.
#include <cvode/cvode.h>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>

#include <string>

#include "pneuma/physiology/simulate.h"

namespace pneuma::physiology::detail {

class CvodeIntegrator {
 public:
  // rhs(t, y, ydot, user_data) as CVODE expects; user_data is passed through.
  CvodeIntegrator(int size, CVRhsFn rhs, void* user_data, const SolverOptions& options);
  ~CvodeIntegrator();
  CvodeIntegrator(const CvodeIntegrator&) = delete;
  CvodeIntegrator& operator=(const CvodeIntegrator&) = delete;

  // Restarts at (t0, y0): the drive may have jumped, so no history is carried across.
  void restart(double t0, const double* y0, double stop_time);
  // Root functions g(t, y) for the integration that follows (CVODE's root finding, located to
  // its root tolerance, ~1e-14 s here); `directions` +1 (rising through 0), -1 (falling) or 0.
  // Kept until the next set_roots; count 0 turns root finding off.
  void set_roots(int count, CVRootFn g, const int* directions);
  // Advances to t (<= stop time) and writes the state there into y. Returns the time reached:
  // t, or the first root's time (then *root is its index; -1 when no root stopped it).
  double advance(double t, double* y, int* root = nullptr);
  SolverStats stats() const;

 private:
  void check(int flag, const char* call) const;
  int size_;
  SUNContext context_ = nullptr;
  N_Vector state_ = nullptr;
  SUNMatrix matrix_ = nullptr;
  SUNLinearSolver solver_ = nullptr;
  void* cvode_ = nullptr;
  long restarts_ = 0;
  int root_count_ = 0;
  SolverStats totals_;
  std::string last_error_;
};

}  // namespace pneuma::physiology::detail
