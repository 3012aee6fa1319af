// Work split into blocks, one thread each.
#pragma once

#include <cstdint>
#include <exception>
#include <system_error>
#include <thread>
#include <vector>

// Runs block(0) ... block(n_blocks - 1): block 0 on this thread, each other on a thread of its own
// (on this one where no thread can be had); an error raised in any block is raised here.
template <typename Block>
void run_blocks(int64_t n_blocks, const Block& block) {
  std::vector<std::exception_ptr> errors(n_blocks);
  const auto guarded = [&](int64_t b) {
    try {
      block(b);
    } catch (...) {
      errors[b] = std::current_exception();
    }
  };
  std::vector<std::thread> workers;
  for (int64_t b = 1; b < n_blocks; ++b) {
    try {
      workers.emplace_back(guarded, b);
    } catch (const std::system_error&) {
      guarded(b);
    }
  }
  guarded(0);
  for (auto& worker : workers) worker.join();
  for (const auto& error : errors)
    if (error) std::rethrow_exception(error);
}
