#pragma once
// Writes frames on a thread of its own while the solver steps the next
// frame: one job in flight, so a run holds at most one frame's copy of the
// world beside its own. A job's failure is rethrown on the caller's thread
// at its next submit() or wait().
#include <condition_variable>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>

namespace triad {

class OutputThread {
 public:
  // With `overlap` false, jobs run at once on the caller's thread.
  explicit OutputThread(bool overlap);
  ~OutputThread();  // finishes the job in flight (its failure is dropped)
  OutputThread(const OutputThread&) = delete;
  OutputThread& operator=(const OutputThread&) = delete;

  // Waits for the job before to finish (rethrowing its failure), then hands
  // `job` over and returns.
  void submit(std::function<void()> job);
  // Waits until no job is in flight; rethrows a failed job's exception.
  void wait();

  bool overlapping() const { return overlap_; }
  // Whether a job is being written now (never, without overlap).
  bool busy() const;
  // Seconds the caller spent blocked in submit() and wait().
  double waitedSeconds() const { return waited_; }
  // Seconds the jobs ran.
  double busySeconds() const;

 private:
  void loop();
  void waitIdle(std::unique_lock<std::mutex>& lock);

  const bool overlap_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::function<void()> job_;
  bool busy_ = false, stop_ = false;
  std::exception_ptr error_;
  double waited_ = 0.0, busy_seconds_ = 0.0;
  std::thread thread_;
};

}  // namespace triad
