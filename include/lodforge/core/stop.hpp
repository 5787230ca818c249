// A cooperative stop request for long computations (the batch runner's asset timeout, a cancel flag): a
// deadline on the steady clock and/or a flag someone else sets. The computation polls requested() at points
// where stopping leaves nothing inconsistent (between blocks of work) and reports that it stopped.
//
//   EvalOptions options{.stop = {.deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30)}};
//   if (evaluate(a, b, options).stopped) ...  // the figures are incomplete
//
// A literal type, so option structs that hold one stay usable in constant expressions, and cheap to copy.
#pragma once

#include <atomic>
#include <chrono>

namespace lodforge {

struct StopRequest {
  using Clock = std::chrono::steady_clock;
  Clock::time_point deadline = Clock::time_point::max();  // max: none
  const std::atomic<bool>* flag = nullptr;                // stop once it reads true; null: none

  // Thread-safe: polled from worker threads.
  bool requested() const {
    return (flag != nullptr && flag->load(std::memory_order_relaxed)) ||
           (deadline != Clock::time_point::max() && Clock::now() > deadline);
  }
};

}  // namespace lodforge
