// SPDX-License-Identifier: GPL-3.0-or-later
// Feature transform + Integer Medial Axis versus a brute-force medial axis by centres of maximal
// balls (BioMesh3D's approach, O(N x boundary)). Run:
//   ./bin/femesher_bench_medial                       (all sizes)
//   ./bin/femesher_bench_medial --benchmark_filter=Ima   (linear-time path only)
// "time_per_voxel" (seconds, SI-prefixed) must stay flat across sizes (linear time); "speedup" = brute force / IMA on the
// same volume.
#include <femesher/stages/FeatureTransform.h>
#include <femesher/stages/MedialAxis.h>

#include <benchmark/benchmark.h>

#include <chrono>
#include <cmath>
#include <limits>
#include <vector>

using namespace femesher;

namespace {

/// A few balls, a torus and a box scaled to an n^3 volume (one material).
std::vector<uint8_t> scene(const Grid3& g) {
  const double n = g.dims[0];
  std::vector<uint8_t> m(g.size(), 0);
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i) {
        const double x = i / n, y = j / n, z = k / n;
        auto sq = [](double a) { return a * a; };
        bool in = sq(x - 0.3) + sq(y - 0.3) + sq(z - 0.3) < sq(0.2);
        in |= sq(x - 0.75) + sq(y - 0.25) + sq(z - 0.7) < sq(0.12);
        in |= sq(std::hypot(x - 0.6, y - 0.65) - 0.2) + sq(z - 0.3) < sq(0.07);
        in |= x > 0.1 && x < 0.45 && y > 0.6 && y < 0.9 && z > 0.55 && z < 0.85;
        m[g.index(i, j, k)] = in ? 1 : 0;
      }
  return m;
}

Grid3 cube(int n) {
  Grid3 g;
  g.dims = {{n, n, n}};
  g.spacing = {{1, 1, 1}};
  return g;
}

MedialAxis ima(const Grid3& g, const std::vector<uint8_t>& region) {
  MedialAxisParameters p;  // default pruning; cost is the same for every variant
  return computeMedialAxis(g, region, p);
}

/// Centres of maximal balls, brute force: r(p) = distance to the nearest boundary feature
/// (searched over every feature voxel adjacent to the region), p is medial iff no 26-neighbour's
/// ball contains p's ball (|p - q| + r(p) <= r(q)).
size_t bruteForceMedialAxis(const Grid3& g, const std::vector<uint8_t>& region) {
  std::vector<std::array<int, 3>> boundary;
  for (int k = -1; k <= g.dims[2]; ++k)
    for (int j = -1; j <= g.dims[1]; ++j)
      for (int i = -1; i <= g.dims[0]; ++i) {
        if (g.inside(i, j, k) && region[g.index(i, j, k)]) continue;
        bool touches = false;
        for (int a = 0; a < 3 && !touches; ++a)
          for (int s = -1; s <= 1; s += 2) {
            std::array<int, 3> q{{i, j, k}};
            q[a] += s;
            if (g.inside(q[0], q[1], q[2]) && region[g.index(q[0], q[1], q[2])]) touches = true;
          }
        if (touches) boundary.push_back({{i, j, k}});
      }
  std::vector<float> r(g.size(), 0.f);
  for (size_t v = 0; v < g.size(); ++v) {
    if (!region[v]) continue;
    const auto c = g.coords(v);
    double best = std::numeric_limits<double>::infinity();
    for (const auto& b : boundary)
      best = std::min(best, g.squaredDistance(c[0] - b[0], c[1] - b[1], c[2] - b[2]));
    r[v] = float(std::sqrt(best));
  }
  size_t medial = 0;
  for (size_t v = 0; v < g.size(); ++v) {
    if (!region[v]) continue;
    const auto c = g.coords(v);
    bool contained = false;
    for (int dk = -1; dk <= 1 && !contained; ++dk)
      for (int dj = -1; dj <= 1 && !contained; ++dj)
        for (int di = -1; di <= 1 && !contained; ++di) {
          if (!di && !dj && !dk) continue;
          if (!g.inside(c[0] + di, c[1] + dj, c[2] + dk)) continue;
          const size_t q = g.index(c[0] + di, c[1] + dj, c[2] + dk);
          if (region[q] && std::sqrt(double(di * di + dj * dj + dk * dk)) + r[v] <= r[q] + 1e-9)
            contained = true;
        }
    medial += contained ? 0 : 1;
  }
  return medial;
}

void BM_FeatureTransformIma(benchmark::State& state) {
  const Grid3 g = cube(int(state.range(0)));
  const auto region = scene(g);
  size_t voxels = 0;
  for (auto _ : state) {
    const MedialAxis a = ima(g, region);
    voxels = a.voxels.size();
    benchmark::DoNotOptimize(voxels);
  }
  state.counters["medial_voxels"] = double(voxels);
  state.counters["time_per_voxel"] = benchmark::Counter(
      double(g.size()), benchmark::Counter::kIsIterationInvariantRate |
                            benchmark::Counter::kInvert);
}
BENCHMARK(BM_FeatureTransformIma)->Arg(64)->Arg(128)->Arg(256)->Unit(benchmark::kMillisecond)
    ->UseRealTime();

void BM_FeatureTransformOnly(benchmark::State& state) {
  const Grid3 g = cube(int(state.range(0)));
  auto feature = scene(g);
  for (auto& b : feature) b = b ? 0 : 1;
  for (auto _ : state) benchmark::DoNotOptimize(featureTransform(g, feature));
  state.counters["time_per_voxel"] = benchmark::Counter(
      double(g.size()), benchmark::Counter::kIsIterationInvariantRate |
                            benchmark::Counter::kInvert);
}
BENCHMARK(BM_FeatureTransformOnly)->Arg(64)->Arg(128)->Arg(256)->Unit(benchmark::kMillisecond)
    ->UseRealTime();

void BM_BruteForceMaximalBalls(benchmark::State& state) {
  const Grid3 g = cube(int(state.range(0)));
  const auto region = scene(g);
  // IMA time on the same volume, for the speed-up.
  const auto t0 = std::chrono::steady_clock::now();
  const int reps = 5;
  for (int i = 0; i < reps; ++i) benchmark::DoNotOptimize(ima(g, region));
  const double imaSeconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() / reps;
  size_t medial = 0;
  double total = 0;
  int iterations = 0;
  for (auto _ : state) {
    const auto s0 = std::chrono::steady_clock::now();
    medial = bruteForceMedialAxis(g, region);
    total += std::chrono::duration<double>(std::chrono::steady_clock::now() - s0).count();
    ++iterations;
    benchmark::DoNotOptimize(medial);
  }
  state.counters["medial_voxels"] = double(medial);
  state.counters["ima_ms"] = imaSeconds * 1e3;
  state.counters["speedup"] = iterations ? (total / iterations) / imaSeconds : 0;
}
// 128^3 takes about 10 s of brute force; 256^3 would take minutes and is left out.
BENCHMARK(BM_BruteForceMaximalBalls)->Arg(32)->Arg(64)->Arg(128)->Unit(benchmark::kMillisecond)
    ->UseRealTime()->Iterations(1);

}  // namespace

BENCHMARK_MAIN();
