// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file Parallel.h
/// Minimal deterministic parallel loop over an index range. The range is split into contiguous
/// chunks, so per-chunk results can be combined in a fixed order. The chunks run on oneTBB's
/// worker pool (Parallel.cxx) inside an arena limited to the requested thread count; this header
/// does not need TBB.

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <exception>
#include <mutex>
#include <thread>
#include <type_traits>
#include <utility>
#include <vector>

namespace femesher {

/// Number of worker threads for a request (0 = hardware concurrency), at least 1.
inline int resolveThreads(int requested) {
  if (requested > 0) return requested;
  const unsigned hc = std::thread::hardware_concurrency();
  return hc == 0 ? 1 : int(hc);
}

/// A non-owning reference to a callable body(begin, end, chunkIndex): what parallelFor hands to
/// the non-template implementation without copying or allocating.
class ChunkBodyRef {
 public:
  template <class F>
  explicit ChunkBodyRef(F& f)
      : object_(const_cast<void*>(static_cast<const void*>(&f))), call_(&invoke<F>) {}
  void operator()(size_t begin, size_t end, int chunk) const { call_(object_, begin, end, chunk); }

 private:
  template <class F>
  static void invoke(void* f, size_t begin, size_t end, int chunk) {
    (*static_cast<F*>(f))(begin, end, chunk);
  }
  void* object_;
  void (*call_)(void*, size_t, size_t, int);
};

/// Runs body(n * c / chunks, n * (c + 1) / chunks, c) for c = 0 .. chunks - 1 (chunks already
/// clamped to [1, n], n > 0) on at most resolveThreads(threads) threads. See parallelFor.
void parallelForChunks(size_t n, int threads, int chunks, ChunkBodyRef body);

/// The number of threads the calling code may run on: inside a parallelFor body, the thread
/// limit of the loop that runs it; elsewhere, the limit of the TBB arena the caller is in (the
/// hardware concurrency outside any arena).
int parallelConcurrency();

/// Calls body(begin, end, chunkIndex) on `chunks` contiguous sub-ranges of [0, n) (default: one
/// per thread); the sub-ranges and their indices depend only on n and chunks. The chunks run on
/// oneTBB's pool, at most `threads` (0 = hardware concurrency) at a time; a call from inside
/// another parallelFor body runs its chunks in the enclosing loop's threads (never more). If a
/// chunk throws, chunks not yet started are skipped and the first exception is re-thrown once
/// the running ones ended.
template <class Body>
void parallelFor(size_t n, int threads, Body&& body, int chunks = 0) {
  if (n == 0) return;
  if (chunks <= 0) chunks = resolveThreads(threads);
  if (size_t(chunks) > n) chunks = int(n);
  using B = std::remove_reference_t<Body>;
  B& ref = body;
  parallelForChunks(n, threads, chunks, ChunkBodyRef(ref));
}

/// Runs body(begin, end, out) on `chunks` contiguous sub-ranges of [0, n) as parallelFor does,
/// each appending what it finds to its own vector `out`, and returns those vectors joined in range
/// order: the same list, in the same order, on any thread count.
template <class T, class Body>
std::vector<T> parallelCollect(size_t n, int threads, int chunks, Body&& body) {
  std::vector<std::vector<T>> parts(size_t(std::max(1, chunks)));
  parallelFor(
      n, threads, [&](size_t begin, size_t end, int chunk) { body(begin, end, parts[size_t(chunk)]); },
      chunks);
  size_t total = 0;
  for (const auto& p : parts) total += p.size();
  std::vector<T> out;
  out.reserve(total);
  for (auto& p : parts) {
    out.insert(out.end(), p.begin(), p.end());
    std::vector<T>().swap(p);
  }
  return out;
}

}  // namespace femesher
