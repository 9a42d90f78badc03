#pragma once
// SIGINT and SIGTERM during a run: the first asks the run to stop at the
// next step boundary (every complete frame and its checkpoint kept, the
// frame in progress dropped, run.json saying why); a second one ends the
// process at once, as the signal's default action would.
#include <string>

namespace triad {

// Installs the handlers for the lifetime of the object, restoring the
// previous ones after.
class InterruptGuard {
 public:
  InterruptGuard();
  ~InterruptGuard();
  InterruptGuard(const InterruptGuard&) = delete;
  InterruptGuard& operator=(const InterruptGuard&) = delete;
};

// The signal received since the guard was installed, or 0.
int pendingInterrupt();

// "SIGINT" or "SIGTERM".
std::string signalName(int sig);

// The exit status of a run ended by signal sig: 128 + sig (130, 143).
inline int interruptedExitStatus(int sig) { return 128 + sig; }

}  // namespace triad
