// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/Parallel.h>
#include <femesher/RunContext.h>
#include <femesher/SpatialHash.h>
#include <femesher/Status.h>
#include <femesher/VecMath.h>
#include <femesher/stages/VolumeMesh.h>
#include <femesher/stages/internal/SpatialOrder.h>
#include <femesher/stages/internal/TetgenJobs.h>

#include <algorithm>
#include <cmath>
#include <cerrno>
#include <cstring>
#include <map>
#include <memory>
#include <sstream>

namespace femesher {

using volume_detail::JobResult;
using volume_detail::TetgenInput;
using volume_detail::TetgenOutput;
using volume_detail::runTetgenJobs;

namespace {

double signedVolume(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  const double v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  const double w[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]};
  return (u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0]) +
          u[2] * (v[0] * w[1] - v[1] * w[0])) / 6.0;
}


/// The labelled Delaunay's labelled tets as plain arrays (exportTets), kept for the stage's
/// fallbacks once the triangulation itself is released: the whole-surface run names its regions
/// with labelAt(), the last resort returns the tets. About a fifth of the triangulation's memory
/// (colin27: 2.8 M tets, 67 MB against 420 MB), so the TetGen helpers run beside a smaller
/// process. Point location goes through a grid of the tets' boxes, built on the first labelAt().
class DelaunayTets {
 public:
  explicit DelaunayTets(const LabelledDelaunay* ld) {
    if (ld) ld->exportTets(points, tets, labels);
  }

  /// The label of the tet that contains canonical point c (0 in none: outside the hull or in a
  /// tet of label 0, as LabelledDelaunay::labelAt). A point on a face shared by two tets takes
  /// the tet it lies deeper in (the larger smallest barycentric coordinate), then the first.
  int labelAt(const Vec3& c) const {
    if (tets.empty()) return 0;
    if (cellStart_.empty()) buildGrid();
    int64_t cell[3];
    for (int a = 0; a < 3; ++a) {
      const double x = std::floor((c[a] - lo_[a]) / cellSize_);
      if (!(x >= 0) || x >= double(dims_[a])) return 0;
      cell[a] = int64_t(x);
    }
    const size_t g = size_t(cell[0] + dims_[0] * (cell[1] + dims_[1] * cell[2]));
    int best = 0;
    double bestDepth = -1e-12;
    for (uint32_t k = cellStart_[g]; k < cellStart_[g + 1]; ++k) {
      const auto& T = tets[cellTets_[k]];
      const Vec3 &a = points[size_t(T[0])], &b = points[size_t(T[1])], &cc = points[size_t(T[2])],
                 &d = points[size_t(T[3])];
      const double v = signedVolume(a, b, cc, d);
      if (v == 0) continue;
      const double w[4] = {signedVolume(c, b, cc, d) / v, signedVolume(a, c, cc, d) / v,
                           signedVolume(a, b, c, d) / v, signedVolume(a, b, cc, c) / v};
      const double depth = std::min({w[0], w[1], w[2], w[3]});
      if (depth > bestDepth) {
        bestDepth = depth;
        best = labels[cellTets_[k]];
      }
    }
    return best;
  }

  std::vector<Vec3> points;
  std::vector<std::array<int32_t, 4>> tets;
  std::vector<int32_t> labels;

 private:
  /// Cells about the mean tet's size (about one tet per cell; larger when the box is thin in one
  /// direction, at most 8 cells per tet); every tet in each cell its box meets (grown by 1e-9 of
  /// the cell, so that a point on a box face finds the tet).
  void buildGrid() const {
    Vec3 hi{-1e300, -1e300, -1e300};
    lo_ = {1e300, 1e300, 1e300};
    for (const Vec3& p : points)
      for (int a = 0; a < 3; ++a) {
        lo_[a] = std::min(lo_[a], p[a]);
        hi[a] = std::max(hi[a], p[a]);
      }
    const double volume = std::max((hi[0] - lo_[0]) * (hi[1] - lo_[1]) * (hi[2] - lo_[2]), 1e-300);
    cellSize_ = uniformGridCell(lo_, hi, std::max(std::cbrt(volume / double(tets.size())), 1e-9),
                                tets.size(), dims_);
    auto range = [&](const std::array<int32_t, 4>& T, int64_t r0[3], int64_t r1[3]) {
      for (int a = 0; a < 3; ++a) {
        double mn = 1e300, mx = -1e300;
        for (int32_t v : T) {
          mn = std::min(mn, points[size_t(v)][a]);
          mx = std::max(mx, points[size_t(v)][a]);
        }
        const double grow = 1e-9 * cellSize_;
        r0[a] = std::clamp<int64_t>(int64_t(std::floor((mn - grow - lo_[a]) / cellSize_)), 0, dims_[a] - 1);
        r1[a] = std::clamp<int64_t>(int64_t(std::floor((mx + grow - lo_[a]) / cellSize_)), 0, dims_[a] - 1);
      }
    };
    const size_t cells = size_t(dims_[0] * dims_[1] * dims_[2]);
    std::vector<uint32_t> start(cells + 1, 0);
    int64_t r0[3], r1[3];
    for (const auto& T : tets) {  // counting pass, then the fill in tet order
      range(T, r0, r1);
      for (int64_t z = r0[2]; z <= r1[2]; ++z)
        for (int64_t y = r0[1]; y <= r1[1]; ++y)
          for (int64_t x = r0[0]; x <= r1[0]; ++x) ++start[size_t(x + dims_[0] * (y + dims_[1] * z)) + 1];
    }
    for (size_t g = 0; g < cells; ++g) start[g + 1] += start[g];
    cellTets_.resize(start[cells]);
    std::vector<uint32_t> fill(start.begin(), start.end() - 1);
    for (size_t t = 0; t < tets.size(); ++t) {
      range(tets[t], r0, r1);
      for (int64_t z = r0[2]; z <= r1[2]; ++z)
        for (int64_t y = r0[1]; y <= r1[1]; ++y)
          for (int64_t x = r0[0]; x <= r1[0]; ++x)
            cellTets_[fill[size_t(x + dims_[0] * (y + dims_[1] * z))]++] = uint32_t(t);
    }
    cellStart_ = std::move(start);
  }

  mutable Vec3 lo_{0, 0, 0};
  mutable double cellSize_ = 1;
  mutable int64_t dims_[3] = {1, 1, 1};
  mutable std::vector<uint32_t> cellStart_, cellTets_;
};

/// The whole interface surface as one TetGen problem (regions numbered by TetGen, -A).
TetgenInput wholeSurface(const BoundarySurface& s, const std::vector<double>& sizes) {
  TetgenInput in;
  in.points = s.points;
  in.triangles = s.triangles;
  std::map<std::pair<uint16_t, uint16_t>, int> ids;
  for (const auto& p : s.trianglePairs) ids.emplace(p, int(ids.size()) + 1);
  for (const auto& p : s.trianglePairs) in.markers.push_back(ids[p]);
  if (sizes.size() == s.points.size()) in.sizes = sizes;
  in.globalId.resize(s.points.size());
  for (size_t i = 0; i < s.points.size(); ++i) in.globalId[i] = int32_t(i);
  return in;
}

/// True when `x` lies inside the closed surface made of `tris` (over `pts`): the parity of the
/// triangles a fixed ray from x crosses (the ray's direction avoids the axes, so points on a box
/// face or a staircase plane do not graze triangles edge-on).
bool insideClosedSurface(const Vec3& x, const std::vector<Vec3>& pts,
                         const std::vector<std::array<int32_t, 3>>& tris) {
  const Vec3 d{0.5773502691896258, 0.5826491074912312, 0.5720514308880204};
  int crossings = 0;
  for (const auto& t : tris) {  // Moller-Trumbore, counting hits at t > 0
    const Vec3& a = pts[size_t(t[0])];
    const Vec3 e1 = sub(pts[size_t(t[1])], a), e2 = sub(pts[size_t(t[2])], a);
    const Vec3 p = cross(d, e2);
    const double det = dot(e1, p);
    if (std::fabs(det) < 1e-300) continue;  // the ray is parallel to the triangle
    const Vec3 s = sub(x, a);
    const double u = dot(s, p) / det;
    if (u < 0 || u > 1) continue;
    const Vec3 q = cross(s, e1);
    const double v = dot(d, q) / det;
    if (v < 0 || u + v > 1) continue;
    if (dot(e2, q) / det > 0) ++crossings;
  }
  return crossings % 2 == 1;
}

/// One TetGen problem per material: its interface triangles, and a hole in every cavity of
/// other materials that they enclose. With -Y the interface triangles are not split, so the
/// materials' meshes share them exactly and together form one conformal mesh.
std::vector<TetgenInput> perMaterialSurfaces(const BoundarySurface& s, const LabelledDelaunay& ld,
                                             const std::vector<double>& sizes, bool& unplaced) {
  std::map<std::pair<uint16_t, uint16_t>, int> ids;
  for (const auto& p : s.trianglePairs) ids.emplace(p, int(ids.size()) + 1);
  int maxLabel = 0;
  for (const auto& p : s.trianglePairs) maxLabel = std::max<int>(maxLabel, p.second);
  const auto cavities = ld.enclosedCavities(s.fromDelaunay ? 1 : 8);
  std::vector<TetgenInput> inputs;
  std::vector<int32_t> local(s.points.size(), -1);
  for (int m = 1; m <= maxLabel; ++m) {
    TetgenInput in;
    in.label = m;
    for (size_t t = 0; t < s.triangles.size(); ++t) {
      const auto& pr = s.trianglePairs[t];
      if (pr.first != m && pr.second != m) continue;
      std::array<int32_t, 3> tri;
      for (int k = 0; k < 3; ++k) {
        const int32_t g = s.triangles[t][k];
        if (local[g] < 0) {
          local[g] = int32_t(in.points.size());
          in.points.push_back(s.points[g]);
          in.globalId.push_back(g);
          if (sizes.size() == s.points.size()) in.sizes.push_back(sizes[g]);
        }
        tri[k] = local[g];
      }
      in.triangles.push_back(tri);
      in.markers.push_back(ids[pr]);
    }
    for (int32_t g : in.globalId) local[g] = -1;
    if (in.triangles.empty()) continue;
    // A hole point must lie outside this material's surface: the cavities come from the
    // labelled Delaunay's regions, and a surface built otherwise (the local Delaunay one) bounds
    // them a little differently; a point inside would carve away the whole material. Each cavity
    // takes its first candidate outside; one with none cannot be meshed per material. (The
    // Delaunay's own surface bounds its regions exactly: its first candidate is outside.)
    if (size_t(m) < cavities.size())
      for (const auto& candidates : cavities[size_t(m)]) {
        auto it = std::find_if(candidates.begin(), candidates.end(), [&](const Vec3& h) {
          return s.fromDelaunay || !insideClosedSurface(h, in.points, in.triangles);
        });
        if (it == candidates.end()) {
          unplaced = true;
          break;
        }
        in.holes.push_back(*it);
      }
    inputs.push_back(std::move(in));
  }
  return inputs;
}

/// Labels the tets of one whole-surface TetGen run: per region a volume-weighted vote of the
/// labelled Delaunay tets at the tets' centroids (without region attributes, per tet).
std::vector<int> voteLabels(const TetgenOutput& out, const std::vector<Vec3>& pts,
                            const DelaunayTets& delaunay, size_t& regions, RunContext& ctx) {
  const int nt = int(out.tets.size() / 4);
  const bool hasRegions = !out.regions.empty();
  std::map<int, std::map<int, double>> votes;
  std::map<int, int> sampled;
  std::vector<int> tetLabel(size_t(nt), -1);
  for (int t = 0; t < nt; ++t) {
    const int32_t* T = &out.tets[4 * size_t(t)];
    const int r = hasRegions ? int(std::lround(out.regions[size_t(t)])) : -1 - t;
    if (hasRegions && sampled[r] >= 400) continue;
    const Vec3 c{(pts[T[0]][0] + pts[T[1]][0] + pts[T[2]][0] + pts[T[3]][0]) / 4,
                 (pts[T[0]][1] + pts[T[1]][1] + pts[T[2]][1] + pts[T[3]][1]) / 4,
                 (pts[T[0]][2] + pts[T[1]][2] + pts[T[2]][2] + pts[T[3]][2]) / 4};
    const int l = delaunay.labelAt(c);
    if (hasRegions) {
      ++sampled[r];
      votes[r][l] += std::fabs(signedVolume(pts[T[0]], pts[T[1]], pts[T[2]], pts[T[3]]));
    } else {
      tetLabel[size_t(t)] = l;
    }
    if ((t & 0xFFFF) == 0) ctx.checkCancel();
  }
  regions = hasRegions ? votes.size() : 0;
  if (!hasRegions) return tetLabel;
  std::map<int, int> regionLabel;
  for (const auto& [r, v] : votes) {
    int best = 0;
    double bestW = -1;
    for (const auto& [l, w] : v)
      if (w > bestW) {
        bestW = w;
        best = l;
      }
    regionLabel[r] = best;
  }
  for (int t = 0; t < nt; ++t)
    tetLabel[size_t(t)] = regionLabel[int(std::lround(out.regions[size_t(t)]))];
  return tetLabel;
}

/// Appends TetGen's tets of `label` (or of every label but 0 when labels are per tet) to the
/// result: the input's points keep their surface index, TetGen's new points are appended.
/// Returns false when TetGen renumbered the input points (then the job cannot be merged).
bool appendTets(const TetgenInput& in, const TetgenOutput& out, const std::vector<int>* tetLabels,
                VolumeMeshResult& result, std::vector<int32_t>& globalOfPoint) {
  const size_t np = out.points.size() / 3;
  if (np < in.points.size()) return false;
  for (size_t i = 0; i < in.points.size(); ++i)
    if (out.points[3 * i] != in.points[i][0] || out.points[3 * i + 1] != in.points[i][1] ||
        out.points[3 * i + 2] != in.points[i][2])
      return false;
  std::vector<int32_t> id(np, -1);
  for (size_t i = 0; i < in.points.size(); ++i) id[i] = in.globalId[i];
  const size_t nt = out.tets.size() / 4;
  for (size_t t = 0; t < nt; ++t) {
    const int l = tetLabels ? (*tetLabels)[t] : in.label;
    if (l == 0) {
      ++result.droppedCavityTets;
      continue;
    }
    std::array<int32_t, 4> T;
    for (int k = 0; k < 4; ++k) {
      const int v = out.tets[4 * t + size_t(k)];
      if (id[size_t(v)] < 0) {  // a Steiner point of this job
        id[size_t(v)] = int32_t(globalOfPoint.size());
        globalOfPoint.push_back(-1);
        result.points.push_back({out.points[3 * size_t(v)], out.points[3 * size_t(v) + 1],
                                 out.points[3 * size_t(v) + 2]});
      }
      T[k] = id[size_t(v)];
    }
    result.tets.push_back(T);
    result.labels.push_back(l);
  }
  return true;
}

/// Keeps only the points that tets use, orients every tet positively and renumbers points and
/// tets in spatial order (internal::spatiallyRenumber: the stages after this one sweep the mesh
/// locally, and TetGen's numbering, material by material, scatters neighbours in memory).
void compactAndOrient(VolumeMeshResult& r) {
  std::vector<int32_t> newId(r.points.size(), -1);
  std::vector<Vec3> pts;
  for (auto& T : r.tets) {
    for (auto& v : T) {
      if (newId[size_t(v)] < 0) {
        newId[size_t(v)] = int32_t(pts.size());
        pts.push_back(r.points[size_t(v)]);
      }
      v = newId[size_t(v)];
    }
    if (signedVolume(pts[T[0]], pts[T[1]], pts[T[2]], pts[T[3]]) < 0) std::swap(T[2], T[3]);
  }
  r.points.swap(pts);
  internal::spatiallyRenumber(r.points, r.tets, r.labels);
}

}  // namespace

VolumeMeshResult buildVolumeMesh(const BoundarySurface& s, const VolumeMeshParameters& params,
                                 RunContext& ctx) {
  return buildVolumeMesh(s, s.delaunay, params, ctx);
}

VolumeMeshResult buildVolumeMesh(const BoundarySurface& s, std::shared_ptr<LabelledDelaunay> ld,
                                 const VolumeMeshParameters& params, RunContext& ctx) {
  VolumeMeshResult result;
  std::ostringstream base;
  base << "pzQ";
  if (params.maxRadiusEdgeRatio > 0) {
    base << "q" << params.maxRadiusEdgeRatio;
    if (params.minDihedralAngle > 0) base << "/" << params.minDihedralAngle;
  }
  const bool sized = params.pointSizes.size() == s.points.size() && params.usePointSizes;
  const std::vector<double> noSizes;
  const std::vector<double>& sizes = sized ? params.pointSizes : noSizes;
  if (sized) base << "m";
  if (params.maxTetVolume > 0) base << "a" << params.maxTetVolume;
  base << "O" << params.optimizationLevel;
  // Guard against run-away refinement: at most 40 Steiner points per surface vertex + 1M.
  base << "S" << (40 * s.points.size() + 1000000);
  const int threads = resolveThreads(ctx.threads());

  // 1. One TetGen run per material, side by side (interfaces kept, so they fit together).
  // What the fallbacks need of the labelled Delaunay, made once the per-material problems have
  // their hole points; then the triangulation goes (when the caller handed it over).
  std::unique_ptr<DelaunayTets> fallback;
  auto releaseDelaunay = [&] {
    if (!fallback) fallback = std::make_unique<DelaunayTets>(ld.get());
    ld.reset();
  };
  if (params.preserveInterfaces && params.perMaterial && ld) {
    const std::string switches = base.str() + "Y";
    bool unplaced = false;
    std::vector<TetgenInput> inputs = perMaterialSurfaces(s, *ld, sizes, unplaced);
    releaseDelaunay();
    std::sort(inputs.begin(), inputs.end(), [](const TetgenInput& a, const TetgenInput& b) {
      if (a.triangles.size() != b.triangles.size()) return a.triangles.size() > b.triangles.size();
      return a.label < b.label;
    });
    // A cavity the material's own surface does not bound where the labelled Delaunay does (no
    // candidate hole point outside it): meshed as one surface below, where TetGen finds the
    // regions itself.
    std::vector<JobResult> jobs;
    if (!unplaced) jobs = runTetgenJobs(inputs, switches, threads, ctx, 0.0, 0.9);
    std::string failure = unplaced ? "a cavity with no hole point outside the material" : "";
    for (size_t j = 0; j < jobs.size() && failure.empty(); ++j)
      if (!jobs[j].ok)
        failure = "material " + std::to_string(inputs[j].label) + ": " + jobs[j].error;
    if (failure.empty()) {
      // Merge in label order (the run order above only serves the scheduling).
      std::vector<size_t> order(inputs.size());
      for (size_t j = 0; j < order.size(); ++j) order[j] = j;
      std::sort(order.begin(), order.end(),
                [&](size_t a, size_t b) { return inputs[a].label < inputs[b].label; });
      result.points = s.points;
      std::vector<int32_t> globalOfPoint(s.points.size());
      for (size_t j : order) {
        if (!appendTets(inputs[j], jobs[j].out, nullptr, result, globalOfPoint)) {
          failure = "TetGen renumbered the surface points of material " +
                    std::to_string(inputs[j].label);
          break;
        }
        result.holePoints += inputs[j].holes.size();
        // Appended: the problem and TetGen's arrays are not read again (a failure below goes to
        // the whole surface, made afresh).
        jobs[j].out = TetgenOutput{};
        inputs[j] = TetgenInput{};
      }
    }
    if (failure.empty()) {
      fallback.reset();
      compactAndOrient(result);
      result.switches = switches;
      result.method = "tetgen";
      result.tetgenRuns = inputs.size();
      result.regions = inputs.size();
      ctx.progress(1.0);
      return result;
    }
    if (unplaced)
      ctx.debug("Volume meshing: " + failure + " (the surface does not bound a cavity of the "
                "labelled Delaunay); the whole surface is meshed at once.");
    else
      ctx.warn("Volume meshing per material with TetGen switches '" + switches + "' failed (" +
               failure + "); the whole surface is meshed at once instead.");
    result = VolumeMeshResult{};
  }

  // 2. The whole surface at once; TetGen numbers the regions, the labelled Delaunay names them.
  releaseDelaunay();
  const TetgenInput whole = wholeSurface(s, sizes);
  std::vector<std::pair<std::string, std::string>> attempts;
  if (params.preserveInterfaces) attempts.emplace_back(base.str() + "AY", "tetgen");
  attempts.emplace_back(base.str() + "A", params.preserveInterfaces ? "tetgen-without-Y" : "tetgen");
  for (const auto& [switches, method] : attempts) {
    ctx.checkCancel();
    auto jobs = runTetgenJobs({whole}, switches, 1, ctx, 0.0, 0.7);
    if (!jobs[0].ok) {
      ctx.warn("Volume meshing with TetGen switches '" + switches + "' failed: " + jobs[0].error + ".");
      continue;
    }
    const TetgenOutput& out = jobs[0].out;
    std::vector<Vec3> pts(out.points.size() / 3);
    for (size_t i = 0; i < pts.size(); ++i)
      pts[i] = {out.points[3 * i], out.points[3 * i + 1], out.points[3 * i + 2]};
    const std::vector<int> labels = voteLabels(out, pts, *fallback, result.regions, ctx);
    // Without Y TetGen may add points on the surface: take its point list as it is.
    TetgenInput all = whole;
    all.points.assign(pts.begin(), pts.begin() + std::ptrdiff_t(std::min(pts.size(), whole.points.size())));
    std::vector<int32_t> globalOfPoint;
    result.points = all.points;
    globalOfPoint.resize(result.points.size());
    appendTets(all, out, &labels, result, globalOfPoint);
    compactAndOrient(result);
    result.switches = switches;
    result.method = method;
    result.tetgenRuns = 1;
    if (method == "tetgen-without-Y")
      ctx.warn("Interface triangles were split by TetGen (switch Y dropped); the mesh is still "
               "conformal but interfaces have extra vertices.");
    ctx.progress(1.0);
    return result;
  }

  ctx.warn("TetGen could not mesh the interface surface; the labelled Delaunay tets of the "
           "surface samples are returned instead (no quality refinement).");
  result.points = std::move(fallback->points);
  result.tets = std::move(fallback->tets);
  result.labels = std::move(fallback->labels);
  for (auto& T : result.tets)
    if (signedVolume(result.points[T[0]], result.points[T[1]], result.points[T[2]],
                     result.points[T[3]]) < 0)
      std::swap(T[2], T[3]);
  result.method = "delaunay-fallback";
  ctx.progress(1.0);
  return result;
}

ReportCounts reportCounts(const VolumeMeshResult& r) {
  return {{"tetgen_regions", double(r.regions)},
          {"tetgen_runs", double(r.tetgenRuns)},
          {"tetgen_hole_points", double(r.holePoints)}};
}

}  // namespace femesher
