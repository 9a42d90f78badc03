#include "app/output_thread.h"

#include <omp.h>

#include <utility>

namespace triad {

OutputThread::OutputThread(bool overlap) : overlap_(overlap) {
  if (overlap_) thread_ = std::thread([this] { loop(); });
}

OutputThread::~OutputThread() {
  if (!overlap_) return;
  {
    std::unique_lock<std::mutex> lock(mutex_);
    cv_.wait(lock, [this] { return !busy_; });
    stop_ = true;
  }
  cv_.notify_all();
  thread_.join();
}

void OutputThread::loop() {
  std::unique_lock<std::mutex> lock(mutex_);
  for (;;) {
    cv_.wait(lock, [this] { return stop_ || busy_; });
    if (!busy_) return;  // stopped with nothing in flight
    std::function<void()> job = std::move(job_);
    lock.unlock();
    const double t0 = omp_get_wtime();
    std::exception_ptr error;
    try {
      job();
    } catch (...) {
      error = std::current_exception();
    }
    const double spent = omp_get_wtime() - t0;
    lock.lock();
    busy_seconds_ += spent;
    if (error && !error_) error_ = error;
    busy_ = false;
    cv_.notify_all();
  }
}

void OutputThread::waitIdle(std::unique_lock<std::mutex>& lock) {
  const double t0 = omp_get_wtime();
  cv_.wait(lock, [this] { return !busy_; });
  waited_ += omp_get_wtime() - t0;
  if (error_) {
    std::exception_ptr e = std::exchange(error_, nullptr);
    std::rethrow_exception(e);
  }
}

void OutputThread::submit(std::function<void()> job) {
  if (!overlap_) {
    const double t0 = omp_get_wtime();
    job();
    busy_seconds_ += omp_get_wtime() - t0;
    return;
  }
  {
    std::unique_lock<std::mutex> lock(mutex_);
    waitIdle(lock);
    job_ = std::move(job);
    busy_ = true;
  }
  cv_.notify_all();
}

void OutputThread::wait() {
  if (!overlap_) return;
  std::unique_lock<std::mutex> lock(mutex_);
  waitIdle(lock);
}

bool OutputThread::busy() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return busy_;
}

double OutputThread::busySeconds() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return busy_seconds_;
}

}  // namespace triad
