#pragma once

#include <omp.h>

namespace triad {

// Accumulates the wall time of a scope into a phase counter.
class PhaseTimer {
 public:
  explicit PhaseTimer(double& acc) : acc_(acc), start_(omp_get_wtime()) {}
  ~PhaseTimer() { acc_ += omp_get_wtime() - start_; }
  PhaseTimer(const PhaseTimer&) = delete;
  PhaseTimer& operator=(const PhaseTimer&) = delete;

 private:
  double& acc_;
  double start_;
};

}  // namespace triad
