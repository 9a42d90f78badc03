// The time a cache line takes to go from one core to another and back: two
// threads, pinned to two CPUs, hand a counter to each other. On the 2-core
// VM where Triad's speeds are measured this round trip is several times a
// desktop's, which is why the solver keeps each block's data on the thread
// that used it last (bench/RESULTS.md, "The solids on the cores that hold
// their data").
//
//   build/bench/bench_core_latency [cpu_a cpu_b [round_trips]]
#include <pthread.h>
#include <sched.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <thread>

namespace {

bool pin(int cpu) {
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(cpu, &set);
  return pthread_setaffinity_np(pthread_self(), sizeof(set), &set) == 0;
}

}  // namespace

int main(int argc, char** argv) {
  const int a = argc > 2 ? std::atoi(argv[1]) : 0, b = argc > 2 ? std::atoi(argv[2]) : 1;
  const long trips = argc > 3 ? std::atol(argv[3]) : 200000;
  alignas(64) std::atomic<long> turn{0};
  bool pinned = true;
  std::thread other([&] {
    pinned = pin(b) && pinned;
    for (long i = 0; i < trips; ++i) {
      while (turn.load(std::memory_order_acquire) != 2 * i + 1) {
      }
      turn.store(2 * i + 2, std::memory_order_release);
    }
  });
  pinned = pin(a) && pinned;
  const auto start = std::chrono::steady_clock::now();
  for (long i = 0; i < trips; ++i) {
    turn.store(2 * i + 1, std::memory_order_release);
    while (turn.load(std::memory_order_acquire) != 2 * i + 2) {
    }
  }
  const auto end = std::chrono::steady_clock::now();
  other.join();
  std::printf("cpus %d and %d%s: round trip %.1f ns over %ld trips\n", a, b,
              pinned ? "" : " (not pinned)",
              std::chrono::duration<double, std::nano>(end - start).count() / double(trips), trips);
  return 0;
}
