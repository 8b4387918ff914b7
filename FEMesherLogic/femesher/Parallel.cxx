// SPDX-License-Identifier: GPL-3.0-or-later
/// \file Parallel.cxx
/// parallelFor on oneTBB: one task per chunk in a task_arena limited to the requested threads.
/// Arenas are created once per thread count and kept for the life of the process (no thread is
/// started per call; TBB's workers are shared by all arenas).

#include "femesher/Parallel.h"

#include <map>
#include <memory>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/partitioner.h>
#include <tbb/task_arena.h>

namespace femesher {
namespace {

/// The thread limit of the parallelFor whose body the calling thread is running (0: none).
thread_local int tlsLoopLimit = 0;

/// Sets tlsLoopLimit for the life of a chunk, restoring the enclosing value (a thread waiting on
/// a nested loop may run another chunk of an outer loop on the same stack).
struct LoopLimitScope {
  explicit LoopLimitScope(int limit) : saved(tlsLoopLimit) { tlsLoopLimit = limit; }
  ~LoopLimitScope() { tlsLoopLimit = saved; }
  LoopLimitScope(const LoopLimitScope&) = delete;
  LoopLimitScope& operator=(const LoopLimitScope&) = delete;
  int saved;
};

/// The arena of `threads` threads, created (and initialised) on first use; thread-safe. The
/// arenas are never destroyed: destroying one at exit, while another static may still use it, is
/// not worth the few bytes.
tbb::task_arena& arenaFor(int threads) {
  static std::mutex mutex;
  static auto* arenas = new std::map<int, std::unique_ptr<tbb::task_arena>>();
  std::lock_guard<std::mutex> lock(mutex);
  auto& slot = (*arenas)[threads];
  if (!slot) {
    slot = std::make_unique<tbb::task_arena>(threads);
    slot->initialize();
  }
  return *slot;
}

}  // namespace

int parallelConcurrency() {
  return tlsLoopLimit > 0 ? tlsLoopLimit : tbb::this_task_arena::max_concurrency();
}

void parallelForChunks(size_t n, int threads, int chunks, ChunkBodyRef body) {
  int t = resolveThreads(threads);
  const int enclosing = tlsLoopLimit;
  if (enclosing > 0) t = std::min(t, enclosing);  // nested: never more than the outer loop
  auto range = [n, chunks](int c, size_t& b, size_t& e) {
    b = n * size_t(c) / size_t(chunks);
    e = n * size_t(c + 1) / size_t(chunks);
  };
  if (t == 1 || chunks == 1) {
    // One thread: loops nested in this one run serially too. One chunk on several threads: this
    // thread is in no arena of t threads, so the enclosing limit stays.
    LoopLimitScope scope(t == 1 ? 1 : enclosing);
    for (int c = 0; c < chunks; ++c) {
      size_t b, e;
      range(c, b, e);
      body(b, e, c);
    }
    return;
  }
  std::exception_ptr error;
  std::mutex errorMutex;
  std::atomic_bool failed{false};
  auto loop = [&] {
    tbb::parallel_for(
        tbb::blocked_range<int>(0, chunks, 1),
        [&](const tbb::blocked_range<int>& r) {
          LoopLimitScope scope(t);
          for (int c = r.begin(); c < r.end(); ++c) {
            if (failed.load(std::memory_order_relaxed)) return;  // like the serial loop: stop
            size_t b, e;
            range(c, b, e);
            try {
              body(b, e, c);
            } catch (...) {
              std::lock_guard<std::mutex> lock(errorMutex);
              if (!error) error = std::current_exception();
              failed.store(true, std::memory_order_relaxed);
            }
          }
        },
        tbb::simple_partitioner());
  };
  if (enclosing > 0 && t == enclosing) {
    // Nested in a loop with the same limit: its arena already has the right size. Isolated, so
    // that a thread waiting here runs only this loop's chunks, not another chunk of the outer
    // loop on top of the one it is in (which may hold a lock this one waits for).
    tbb::this_task_arena::isolate(loop);
  } else {
    arenaFor(t).execute(loop);
  }
  if (error) std::rethrow_exception(error);
}

}  // namespace femesher
