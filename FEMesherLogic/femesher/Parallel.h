// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file Parallel.h
/// Minimal deterministic parallel loop over an index range with std::thread. The range is split
/// into contiguous chunks, so per-chunk results can be combined in a fixed order.

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace femesher {

/// Number of worker threads for a request (0 = hardware concurrency), at least 1.
inline int resolveThreads(int requested) {
  if (requested > 0) return requested;
  const unsigned hc = std::thread::hardware_concurrency();
  return hc == 0 ? 1 : int(hc);
}

/// Calls body(begin, end, chunkIndex) on `chunks` contiguous sub-ranges of [0, n) (default: one
/// per thread). Exceptions from any chunk are re-thrown (the first one) after all threads joined.
template <class Body>
void parallelFor(size_t n, int threads, Body&& body, int chunks = 0) {
  const int t = resolveThreads(threads);
  if (chunks <= 0) chunks = t;
  chunks = int(std::max<size_t>(1, std::min<size_t>(size_t(chunks), n)));
  if (n == 0) return;
  if (t == 1 || chunks == 1) {
    for (int c = 0; c < chunks; ++c) body(n * c / chunks, n * (c + 1) / chunks, c);
    return;
  }
  std::exception_ptr error;
  std::mutex errorMutex;
  std::vector<std::thread> pool;
  std::atomic_int next{0};
  auto worker = [&] {
    for (;;) {
      const int c = next.fetch_add(1);
      if (c >= chunks) return;
      try {
        body(n * c / chunks, n * (c + 1) / chunks, c);
      } catch (...) {
        std::lock_guard<std::mutex> lock(errorMutex);
        if (!error) error = std::current_exception();
      }
    }
  };
  const int workers = std::min(t, chunks);
  pool.reserve(workers);
  for (int w = 0; w < workers; ++w) pool.emplace_back(worker);
  for (auto& th : pool) th.join();
  if (error) std::rethrow_exception(error);
}

}  // namespace femesher
