// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/stages/MedialAxis.h>

#include <femesher/Parallel.h>
#include <femesher/RunContext.h>
#include <femesher/Status.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <map>
#include <string>

namespace femesher {

namespace {

/// Chunks of the loops whose per-chunk results are concatenated or merged: fixed, so the result
/// does not depend on the thread count.
constexpr int kChunks = 64;

struct Box {
  std::array<int, 3> lo{{0, 0, 0}}, hi{{-1, -1, -1}};  // inclusive; empty when hi < lo
  bool empty() const { return hi[0] < lo[0]; }
  void add(int i, int j, int k) {
    if (empty()) {
      lo = hi = {{i, j, k}};
      return;
    }
    lo = {{std::min(lo[0], i), std::min(lo[1], j), std::min(lo[2], k)}};
    hi = {{std::max(hi[0], i), std::max(hi[1], j), std::max(hi[2], k)}};
  }
  void add(const Box& b) {
    if (b.empty()) return;
    add(b.lo[0], b.lo[1], b.lo[2]);
    add(b.hi[0], b.hi[1], b.hi[2]);
  }
};

void checkParameters(const MedialAxisParameters& p) {
  if (!(p.gamma >= 0) || !std::isfinite(p.gamma))
    throw Error(ErrorCode::InvalidArgument,
                "Medial axis: gamma must be a finite number >= 0 (got " + std::to_string(p.gamma) +
                    ").");
  if (!(p.gammaConstant >= 0) || !std::isfinite(p.gammaConstant))
    throw Error(ErrorCode::InvalidArgument,
                "Medial axis: the constant pruning floor must be a finite number >= 0 (got " +
                    std::to_string(p.gammaConstant) + ").");
}

/// IMA of the region inside `box` (region voxels all lie in the box). `inRegion(globalIndex)`.
template <class InRegion>
MedialAxis imaInBox(const Grid3& grid, const Box& box, InRegion inRegion,
                    const MedialAxisParameters& params, RunContext* ctx) {
  MedialAxis result;
  if (box.empty()) return result;
  // Local grid: the box grown by one voxel; voxels outside the volume are (virtual) features.
  Grid3 local;
  local.spacing = grid.spacing;
  std::array<int, 3> lo;
  for (int a = 0; a < 3; ++a) {
    lo[a] = box.lo[a] - 1;
    local.dims[a] = box.hi[a] - box.lo[a] + 3;
  }
  const size_t n = local.size();
  std::vector<uint8_t> region(n, 0);
  const int threads = params.threads;
  parallelFor(size_t(local.dims[1]) * local.dims[2], threads, [&](size_t b, size_t e, int) {
    for (size_t line = b; line < e; ++line) {
      const int j = int(line % local.dims[1]), k = int(line / local.dims[1]);
      const int gj = j + lo[1], gk = k + lo[2];
      if (gj < 0 || gk < 0 || gj >= grid.dims[1] || gk >= grid.dims[2]) continue;
      for (int i = 0; i < local.dims[0]; ++i) {
        const int gi = i + lo[0];
        if (gi < 0 || gi >= grid.dims[0]) continue;
        region[local.index(i, j, k)] = inRegion(grid.index(gi, gj, gk)) ? 1 : 0;
      }
    }
  });
  std::vector<uint8_t> feature(n);
  parallelFor(n, threads, [&](size_t b, size_t e, int) {
    for (size_t v = b; v < e; ++v) feature[v] = region[v] ? 0 : 1;
  }, kChunks);
  const std::vector<uint32_t> ft = featureTransform(local, feature, threads, ctx);
  feature.clear();
  feature.shrink_to_fit();

  // Pruning constants in voxel units u = geometric mean spacing.
  const auto& S = grid.spacing;
  const double u = (S[0] == S[1] && S[1] == S[2]) ? S[0] : std::cbrt(S[0] * S[1] * S[2]);
  const double invU2 = 1.0 / (u * u);
  const std::array<double, 3> w{{S[0] * S[0], S[1] * S[1], S[2] * S[2]}};
  const double gamma = params.gamma, gamma2 = gamma * gamma;
  const double gc2 = params.gammaConstant * params.gammaConstant;
  const MedialAxisPruning pruning = params.pruning;

  // Evaluate the pair (p, q = p + e_axis): 1 when it spans the axis (0 otherwise), with c.
  auto spans = [&](size_t p, size_t q, int axis, double& c) -> int {
    const uint32_t fp = ft[p], fq = ft[q];
    if (fp == kNoFeature || fq == kNoFeature || fp == fq) return 0;
    const auto cp = local.coords(p), cfp = local.coords(fp), cfq = local.coords(fq);
    std::array<int, 3> cq = cp;
    cq[axis] += 1;
    long long idx2 = 0;
    double dist2 = 0, sumR2 = 0, dotPQ = 0;
    c = 0;
    for (int a = 0; a < 3; ++a) {
      const int df = cfp[a] - cfq[a];
      idx2 += (long long)df * df;
      dist2 += w[a] * double(df) * df;
      const int r = (cp[a] - cfp[a]) + (cq[a] - cfq[a]);
      sumR2 += w[a] * double(r) * r;
      dotPQ += w[a] * double(cp[a] - cq[a]) * df;
      c += w[a] * double(df) * double(cfp[a] + cfq[a] - cp[a] - cq[a]);
    }
    if (idx2 <= 1) return 0;
    // Thresholds are compared with a relative margin of 1e-9 so that rounding of the spacing
    // never decides a mathematical tie (e.g. D² = γ² exactly is "not greater").
    const double D2 = dist2 * invU2 * (1 - 1e-9);
    const double R2 = sumR2 * invU2 / 4;
    switch (pruning) {
      case MedialAxisPruning::None:
        break;
      case MedialAxisPruning::Constant:
        if (!(D2 > gamma2)) return 0;
        break;
      case MedialAxisPruning::Linear:
        if (!(D2 > 1 + gamma2 * R2)) return 0;
        break;
      case MedialAxisPruning::SquareRoot:
        if (!(D2 > gamma * (2 * std::sqrt(R2) + 2 * dotPQ * invU2 + 1.5))) return 0;
        break;
      case MedialAxisPruning::ConstantLinear:
        if (!(D2 > 1 + gamma2 * R2)) return 0;
        if (!(D2 > gc2)) return 0;
        break;
    }
    return 1;
  };

  // Each region voxel decides its own mark from its 6 pairs (race-free, order-independent).
  std::vector<uint8_t> mark(n, 0);
  const int nx = local.dims[0], ny = local.dims[1], nz = local.dims[2];
  const std::array<size_t, 3> step{{1, size_t(nx), size_t(nx) * ny}};
  parallelFor(size_t(nz), threads, [&](size_t b, size_t e, int) {
    if (ctx) ctx->checkCancel();
    for (size_t k = b; k < e; ++k)
      for (int j = 0; j < ny; ++j)
        for (int i = 0; i < nx; ++i) {
          const size_t p = local.index(i, j, int(k));
          if (!region[p]) continue;
          const std::array<int, 3> cp{{i, j, int(k)}};
          bool m = false;
          for (int a = 0; a < 3 && !m; ++a) {
            double c;
            if (cp[a] + 1 < local.dims[a] && spans(p, p + step[a], a, c) && c >= 0) m = true;
            if (!m && cp[a] > 0 && spans(p - step[a], p, a, c) && c <= 0) m = true;
          }
          mark[p] = m ? 1 : 0;
        }
  }, threads == 1 ? 1 : resolveThreads(threads) * 4);

  // The marked voxels in local order, per chunk, concatenated in chunk order.
  std::vector<MedialAxis> parts(kChunks);
  parallelFor(n, threads, [&](size_t b, size_t e, int chunk) {
    MedialAxis& part = parts[size_t(chunk)];
    for (size_t p = b; p < e; ++p) {
      if (!mark[p]) continue;
      const auto c = local.coords(p);
      part.voxels.push_back(uint32_t(grid.index(c[0] + lo[0], c[1] + lo[1], c[2] + lo[2])));
      part.radius.push_back(float(std::sqrt(featureSquaredDistance(local, p, ft[p]))));
    }
  }, kChunks);
  size_t total = 0;
  for (const auto& part : parts) total += part.voxels.size();
  result.voxels.reserve(total);
  result.radius.reserve(total);
  for (const auto& part : parts) {
    result.voxels.insert(result.voxels.end(), part.voxels.begin(), part.voxels.end());
    result.radius.insert(result.radius.end(), part.radius.begin(), part.radius.end());
  }
  // Local order (x fastest) maps to ascending global order already, since the box keeps
  // the axis order; no sort needed.
  return result;
}

}  // namespace

bool parseMedialAxisPruning(const std::string& text, MedialAxisPruning& out) {
  std::string t;
  for (char ch : text) t.push_back(char(std::tolower(static_cast<unsigned char>(ch))));
  if (t == "none" || t == "exact") out = MedialAxisPruning::None;
  else if (t == "constant") out = MedialAxisPruning::Constant;
  else if (t == "linear") out = MedialAxisPruning::Linear;
  else if (t == "sqrt" || t == "squareroot" || t == "square-root") out = MedialAxisPruning::SquareRoot;
  else if (t == "constant-linear" || t == "combined" || t == "constantlinear")
    out = MedialAxisPruning::ConstantLinear;
  else return false;
  return true;
}

const char* medialAxisPruningName(MedialAxisPruning p) {
  switch (p) {
    case MedialAxisPruning::None: return "none";
    case MedialAxisPruning::Constant: return "constant";
    case MedialAxisPruning::Linear: return "linear";
    case MedialAxisPruning::SquareRoot: return "sqrt";
    case MedialAxisPruning::ConstantLinear: return "constant-linear";
  }
  return "unknown";
}

MedialAxis computeMedialAxis(const Grid3& grid, const std::vector<uint8_t>& inRegion,
                             const MedialAxisParameters& params, RunContext* ctx) {
  checkParameters(params);
  if (inRegion.size() != grid.size())
    throw Error(ErrorCode::InvalidArgument,
                "Medial axis: the region mask has " + std::to_string(inRegion.size()) +
                    " values but the grid has " + std::to_string(grid.size()) + " voxels.");
  Box box;
  for (int k = 0; k < grid.dims[2]; ++k)
    for (int j = 0; j < grid.dims[1]; ++j) {
      const size_t base = grid.index(0, j, k);
      for (int i = 0; i < grid.dims[0]; ++i)
        if (inRegion[base + i]) box.add(i, j, k);
    }
  return imaInBox(grid, box, [&](size_t v) { return inRegion[v] != 0; }, params, ctx);
}

namespace {

Grid3 gridOf(const LabelVolume& volume) {
  Grid3 g;
  g.dims = volume.dims;
  g.spacing = volume.spacing;
  return g;
}

void checkVolume(const LabelVolume& volume) {
  if (volume.labels.size() != volume.voxelCount())
    throw Error(ErrorCode::InvalidArgument,
                "Medial axis: the label map has " + std::to_string(volume.labels.size()) +
                    " values for " + std::to_string(volume.voxelCount()) + " voxels.");
}

std::map<int32_t, Box> labelBoxes(const LabelVolume& volume, int threads) {
  // Per chunk of z-planes, then merged (a union of boxes: any order gives the same boxes).
  std::vector<std::map<int32_t, Box>> parts(kChunks);
  parallelFor(size_t(std::max(0, volume.dims[2])), threads, [&](size_t kb, size_t ke, int chunk) {
    std::map<int32_t, Box>& boxes = parts[size_t(chunk)];
    int32_t last = 0;
    Box* lastBox = nullptr;
    for (int k = int(kb); k < int(ke); ++k)
      for (int j = 0; j < volume.dims[1]; ++j) {
        const size_t base = volume.index(0, j, k);
        for (int i = 0; i < volume.dims[0]; ++i) {
          const int32_t l = volume.labels[base + i];
          if (!lastBox || l != last) {
            lastBox = &boxes[l];
            last = l;
          }
          lastBox->add(i, j, k);
        }
      }
  }, kChunks);
  std::map<int32_t, Box> boxes;
  for (const auto& part : parts)
    for (const auto& [l, b] : part) boxes[l].add(b);
  return boxes;
}

}  // namespace

MedialAxis computeLabelMedialAxis(const LabelVolume& volume, int32_t label,
                                  const MedialAxisParameters& params, RunContext* ctx) {
  checkParameters(params);
  checkVolume(volume);
  const auto boxes = labelBoxes(volume, params.threads);
  const auto it = boxes.find(label);
  if (it == boxes.end()) return {};
  const auto& labels = volume.labels;
  return imaInBox(gridOf(volume), it->second, [&](size_t v) { return labels[v] == label; },
                  params, ctx);
}

LabelMedialAxes computeAllMedialAxes(const LabelVolume& volume, const MedialAxisParameters& params,
                                     RunContext& context, double progressFrom, double progressTo) {
  RunContext* ctx = &context;
  checkParameters(params);
  checkVolume(volume);
  LabelMedialAxes out;
  out.grid = gridOf(volume);
  out.unionMask.assign(volume.voxelCount(), 0);
  const auto boxes = labelBoxes(volume, params.threads);
  // Work estimate per label: its box volume.
  double total = 0, done = 0;
  for (const auto& [l, b] : boxes)
    total += double(b.hi[0] - b.lo[0] + 3) * (b.hi[1] - b.lo[1] + 3) * (b.hi[2] - b.lo[2] + 3);
  const auto& labels = volume.labels;
  for (const auto& [label, box] : boxes) {
    const int32_t l = label;
    MedialAxis axis =
        imaInBox(out.grid, box, [&](size_t v) { return labels[v] == l; }, params, ctx);
    for (uint32_t v : axis.voxels) out.unionMask[v] = 1;
    out.labels.push_back(label);
    out.axes.push_back(std::move(axis));
    done += double(box.hi[0] - box.lo[0] + 3) * (box.hi[1] - box.lo[1] + 3) *
            (box.hi[2] - box.lo[2] + 3);
    if (ctx) ctx->progress(progressFrom + (progressTo - progressFrom) * (total > 0 ? done / total : 1.0));
  }
  return out;
}

size_t LabelMedialAxes::voxelCount() const {
  size_t n = 0;
  for (const auto& a : axes) n += a.voxels.size();
  return n;
}

std::vector<int32_t> LabelMedialAxes::labelImage(int32_t notMedial) const {
  std::vector<int32_t> image(grid.size(), notMedial);
  for (size_t i = 0; i < axes.size(); ++i)
    for (uint32_t v : axes[i].voxels) image[v] = labels[i];
  return image;
}

}  // namespace femesher
