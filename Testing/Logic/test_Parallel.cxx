// SPDX-License-Identifier: GPL-3.0-or-later
// parallelFor (Parallel.h) on oneTBB: the chunks' sub-ranges and indices, exceptions, nested
// loops, and the thread limit.
#include <femesher/Parallel.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <tuple>
#include <vector>

using namespace femesher;

namespace {

using Chunk = std::tuple<size_t, size_t, int>;

std::vector<Chunk> chunksOf(size_t n, int threads, int chunks) {
  std::vector<Chunk> seen;
  std::mutex m;
  parallelFor(n, threads, [&](size_t b, size_t e, int c) {
    std::lock_guard<std::mutex> lock(m);
    seen.emplace_back(b, e, c);
  }, chunks);
  std::sort(seen.begin(), seen.end());
  return seen;
}

/// Counts the bodies running at once and keeps the largest count.
struct Concurrency {
  std::atomic_int now{0}, most{0};
  void enter() {
    const int v = ++now;
    int m = most.load();
    while (v > m && !most.compare_exchange_weak(m, v)) {
    }
  }
  void leave() { --now; }
};

}  // namespace

TEST(Parallel, ChunkRangesAndIndicesIndependentOfThreads) {
  const std::vector<Chunk> expected = {{0, 2, 0}, {2, 5, 1}, {5, 7, 2}, {7, 10, 3}};
  for (int threads : {1, 2, 3, 8}) EXPECT_EQ(chunksOf(10, threads, 4), expected) << threads;
  // More chunks than items: one item per chunk.
  for (int threads : {1, 2}) {
    const auto c = chunksOf(3, threads, 7);
    ASSERT_EQ(c.size(), 3u);
    for (int i = 0; i < 3; ++i) EXPECT_EQ(c[size_t(i)], Chunk(size_t(i), size_t(i + 1), i));
  }
  // Default: one chunk per thread.
  EXPECT_EQ(chunksOf(100, 3, 0).size(), 3u);
  EXPECT_EQ(chunksOf(100, 1, 0).size(), 1u);
  EXPECT_TRUE(chunksOf(0, 2, 4).empty());
  // Many chunks cover the range exactly once.
  const auto many = chunksOf(100000, 2, 1000);
  ASSERT_EQ(many.size(), 1000u);
  size_t at = 0;
  for (int c = 0; c < 1000; ++c) {
    EXPECT_EQ(std::get<0>(many[size_t(c)]), at);
    EXPECT_EQ(std::get<2>(many[size_t(c)]), c);
    at = std::get<1>(many[size_t(c)]);
  }
  EXPECT_EQ(at, 100000u);
}

// parallelCollect joins what each chunk found in range order: the same list on any thread count
// and chunk count, whatever order the chunks ran in.
TEST(Parallel, CollectJoinsTheChunksInRangeOrder) {
  std::vector<size_t> expected;
  for (size_t i = 0; i < 10000; ++i)
    if (i % 7 == 3) expected.push_back(i);
  for (int threads : {1, 2, 4})
    for (int chunks : {1, 5, 64}) {
      const std::vector<size_t> got = parallelCollect<size_t>(
          10000, threads, chunks, [](size_t begin, size_t end, std::vector<size_t>& out) {
            for (size_t i = begin; i < end; ++i)
              if (i % 7 == 3) out.push_back(i);
          });
      EXPECT_EQ(got, expected) << threads << " threads, " << chunks << " chunks";
    }
  EXPECT_TRUE((parallelCollect<int>(0, 2, 4, [](size_t, size_t, std::vector<int>&) {})).empty());
}

TEST(Parallel, FirstExceptionIsRethrown) {
  for (int threads : {1, 2, 4}) {
    std::atomic_int ran{0};
    try {
      parallelFor(100, threads, [&](size_t, size_t, int c) {
        ++ran;
        if (c == 5) throw std::runtime_error("chunk 5");
      }, 20);
      ADD_FAILURE() << "no exception, threads " << threads;
    } catch (const std::runtime_error& e) {
      EXPECT_STREQ(e.what(), "chunk 5");
    }
    EXPECT_GE(ran.load(), 1);
    EXPECT_LE(ran.load(), 20);
    // The pool is still usable after an exception.
    EXPECT_EQ(chunksOf(10, threads, 4).size(), 4u);
  }
}

TEST(Parallel, ThreadLimitHonoured) {
  for (int threads : {1, 2, 3}) {
    Concurrency conc;
    std::atomic_int wrongLimit{0};
    std::mutex m;
    std::vector<std::thread::id> ids;
    parallelFor(64, threads, [&](size_t, size_t, int) {
      conc.enter();
      if (parallelConcurrency() != threads) ++wrongLimit;
      {
        std::lock_guard<std::mutex> lock(m);
        ids.push_back(std::this_thread::get_id());
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
      conc.leave();
    }, 64);
    std::sort(ids.begin(), ids.end());
    ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
    EXPECT_EQ(wrongLimit.load(), 0) << threads;
    EXPECT_LE(conc.most.load(), threads);
    EXPECT_LE(int(ids.size()), threads);
  }
}

TEST(Parallel, NestedLoopsStayWithinTheOuterLimit) {
  for (int inner : {0, 1, 2, 8}) {
    Concurrency conc;
    std::atomic_int calls{0}, overLimit{0};
    std::atomic<size_t> covered{0};
    std::mutex outerLock;  // held across the nested loop: must not deadlock
    parallelFor(8, 2, [&](size_t b, size_t e, int) {
      for (size_t i = b; i < e; ++i) {
        std::lock_guard<std::mutex> lock(outerLock);
        parallelFor(1000, inner, [&](size_t ib, size_t ie, int) {
          conc.enter();
          ++calls;
          if (parallelConcurrency() > 2) ++overLimit;
          covered += ie - ib;
          conc.leave();
        }, 10);
      }
    }, 8);
    EXPECT_EQ(calls.load(), 80) << inner;
    EXPECT_EQ(covered.load(), 8000u) << inner;
    EXPECT_EQ(overLimit.load(), 0) << inner;
    EXPECT_LE(conc.most.load(), 2) << inner;
  }
}

TEST(Parallel, ConcurrentCallersShareThePool) {
  // Loops started from several threads at once (e.g. the app's worker and a preview) all finish.
  std::vector<std::thread> callers;
  std::atomic<size_t> sum{0};
  for (int k = 0; k < 4; ++k)
    callers.emplace_back([&, k] {
      for (int rep = 0; rep < 20; ++rep)
        parallelFor(1000, 1 + k % 3, [&](size_t b, size_t e, int) { sum += e - b; }, 16);
    });
  for (auto& t : callers) t.join();
  EXPECT_EQ(sum.load(), 4u * 20u * 1000u);
}
