// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/StageTable.h>
#include <femesher/Parallel.h>
#include <femesher/RunContext.h>
#include <femesher/SpatialHash.h>
#include <femesher/stages/SurfaceSampling.h>

#include <vtkDiscreteFlyingEdges3D.h>
#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkCellArray.h>
#include <vtkUnsignedShortArray.h>
#include <vtkIdList.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>
#include <unordered_map>

namespace femesher {

namespace {

}  // namespace

SurfaceSamples sampleInterfaces(const IndicatorField& field, const LabelVolume& input,
                                const SurfaceSamplingParameters& params, RunContext& ctx) {
  const PreprocessedVolume& vol = field.volume();
  SurfaceSamples out;
  const auto t0 = std::chrono::steady_clock::now();
  auto seconds = [&] {
    return std::to_string(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  };

  // --- Marching cubes on the label grid (VTK) ----------------------------------------------
  vtkNew<vtkImageData> image;
  image->SetDimensions(vol.dims[0], vol.dims[1], vol.dims[2]);
  image->SetSpacing(1, 1, 1);
  image->SetOrigin(0, 0, 0);
  vtkNew<vtkUnsignedShortArray> scalars;
  scalars->SetArray(const_cast<uint16_t*>(vol.labels.data()), vtkIdType(vol.labels.size()), 1);
  image->GetPointData()->SetScalars(scalars);
  vtkNew<vtkDiscreteFlyingEdges3D> mc;
  mc->SetInputData(image);
  const int nMat = vol.materialCount();
  mc->SetNumberOfContours(nMat);
  for (int m = 1; m <= nMat; ++m) mc->SetValue(m - 1, m);
  mc->ComputeNormalsOff();
  mc->ComputeGradientsOff();
  mc->ComputeScalarsOff();
  mc->Update();
  ctx.progress(0.3);
  vtkPolyData* surface = mc->GetOutput();
  const vtkIdType nPts = surface->GetNumberOfPoints();
  out.isosurfaceTriangles = size_t(surface->GetNumberOfPolys());
  ctx.debug("SurfaceSampling: marching cubes " + seconds() + " s");

  // --- Relocate every vertex onto the smooth interface --------------------------------------
  // Each vertex sits at the midpoint of a grid edge between two different labels.
  std::vector<int64_t> edgeKey(nPts, -1);
  std::vector<SurfaceSample> candidates(nPts);
  parallelFor(size_t(nPts), ctx.threads(), [&](size_t b, size_t e, int) {
    for (size_t id = b; id < e; ++id) {
      double x[3];
      surface->GetPoint(vtkIdType(id), x);
      int axis = -1;
      int p[3];
      for (int a = 0; a < 3; ++a) {
        const double fl = std::floor(x[a]);
        if (std::fabs(x[a] - fl - 0.5) < 1e-3) axis = a;
        p[a] = int(std::lround(x[a]));
      }
      if (axis < 0) continue;
      p[axis] = int(std::floor(x[axis]));
      int q[3] = {p[0], p[1], p[2]};
      q[axis] += 1;
      const int la = vol.at(p[0], p[1], p[2]), lb = vol.at(q[0], q[1], q[2]);
      if (la == lb) continue;
      const double g0 = double(field.value(la, p[0], p[1], p[2])) - field.value(lb, p[0], p[1], p[2]);
      const double g1 = double(field.value(la, q[0], q[1], q[2])) - field.value(lb, q[0], q[1], q[2]);
      if (!(g0 > 0 && g1 < 0)) continue;
      const double t = g0 / (g0 - g1);
      Vec3 pos{double(p[0]), double(p[1]), double(p[2])};
      pos[axis] += t;
      int corner[8];
      const int nc = field.cornerLabels(pos, corner);
      if (nc > 2) {
        const int owner = field.argmax(pos);
        if (owner != la && owner != lb) continue;  // inside a third material near a junction
      }
      SurfaceSample s;
      s.local = pos;
      s.a = uint16_t(std::min(la, lb));
      s.b = uint16_t(std::max(la, lb));
      s.junction = nc > 2;
      candidates[id] = s;
      edgeKey[id] = int64_t(vol.index(p[0], p[1], p[2])) * 3 + axis;
    }
  }, 64);  // per-vertex results; uneven costs (junction vertices), so many chunks
  ctx.progress(0.5);
  ctx.debug("SurfaceSampling: vertices relocated " + seconds() + " s");

  // Deduplicate (both sides of an interface produce the same edge vertex).
  std::vector<uint32_t> order;
  order.reserve(size_t(nPts));
  for (vtkIdType id = 0; id < nPts; ++id)
    if (edgeKey[id] >= 0) order.push_back(uint32_t(id));
  std::sort(order.begin(), order.end(),
            [&](uint32_t a, uint32_t b) { return edgeKey[a] < edgeKey[b]; });
  order.erase(std::unique(order.begin(), order.end(),
                          [&](uint32_t a, uint32_t b) { return edgeKey[a] == edgeKey[b]; }),
              order.end());
  out.all.reserve(order.size());
  std::vector<uint64_t> priority;
  priority.reserve(order.size());
  for (uint32_t id : order) {
    out.all.push_back(candidates[id]);
    priority.push_back(mix64(uint64_t(edgeKey[id]) ^ mix64(params.seed)) >> 1);
  }
  ctx.progress(0.6);
  ctx.debug("SurfaceSampling: deduplicated " + seconds() + " s");

  // --- Poisson-disk selection ----------------------------------------------------------------
  // Candidates in a seeded random order (junction-cell ones first) are kept when no kept sample
  // of the same interface is closer than 0.75 x their mean size (0.4 x that for other
  // interfaces). The sizing field is graded (h_j <= h_i + 0.4 d), so a conflicting neighbour is
  // never farther than 0.375 (h_i + min(h_max, 2 h_i)).
  const size_t nAll = out.all.size();
  std::vector<Vec3> cpos(nAll);
  std::vector<float> hs(nAll);
  parallelFor(nAll, ctx.threads(), [&](size_t b, size_t e, int) {
    for (size_t i = b; i < e; ++i) {
      cpos[i] = vol.localToCanonical(out.all[i].local);
      hs[i] = float(params.sizing ? params.sizing(cpos[i]) : params.targetEdgeLength);
    }
  });
  double hMax = 1e-9;
  Vec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
  for (size_t i = 0; i < nAll; ++i) {
    hMax = std::max(hMax, double(hs[i]));
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], cpos[i][a]);
      hi[a] = std::max(hi[a], cpos[i][a]);
    }
  }
  std::vector<float> sortedH(hs);
  std::nth_element(sortedH.begin(), sortedH.begin() + long(nAll / 2), sortedH.end());
  const double hMedian = nAll ? double(sortedH[nAll / 2]) : 1.0;
  std::vector<uint32_t> idx(nAll);
  std::iota(idx.begin(), idx.end(), 0u);
  std::sort(idx.begin(), idx.end(), [&](uint32_t a, uint32_t b) {
    if (out.all[a].junction != out.all[b].junction) return out.all[a].junction;
    return priority[a] < priority[b];
  });
  PointGrid grid(lo, hi, 0.75 * hMedian, nAll / 8 + 1);
  size_t processed = 0;
  for (uint32_t i : idx) {
    if ((++processed & 0xFFFF) == 0) ctx.progress(0.6 + 0.35 * double(processed) / double(nAll));
    const SurfaceSample& s = out.all[i];
    const Vec3& c = cpos[i];
    const double reach = 0.375 * (double(hs[i]) + std::min(hMax, 2.0 * double(hs[i])));
    bool ok = true;
    grid.forEachNear(c, reach, [&](uint32_t j) {
      if (!ok) return;
      const SurfaceSample& t = out.all[j];
      const Vec3& d = cpos[j];
      const double dist2 = (c[0] - d[0]) * (c[0] - d[0]) + (c[1] - d[1]) * (c[1] - d[1]) +
                           (c[2] - d[2]) * (c[2] - d[2]);
      const bool same = s.a == t.a && s.b == t.b;
      const double rij = 0.75 * 0.5 * (double(hs[i]) + double(hs[j]));
      const double lim = same ? rij : 0.4 * rij;
      if (dist2 < lim * lim) ok = false;
    });
    if (!ok) continue;
    grid.insert(i, c);
    out.selected.push_back(i);
  }
  ctx.debug("SurfaceSampling: Poisson-disk selection " + seconds() + " s");
  // --- Preview: the selected samples per interface, in LPS ---------------------------------
  if (ctx.wantsPreview()) {
    auto snap = std::make_shared<PreviewSnapshot>();
    snap->stage = stageInfo(StageId::SurfaceSampling).key;
    snap->kind = "points";
    std::unordered_map<uint32_t, int32_t> groupOf;
    for (uint32_t i : out.selected) {
      const SurfaceSample& s = out.all[i];
      const uint32_t key = (uint32_t(s.a) << 16) | s.b;
      auto it = groupOf.find(key);
      if (it == groupOf.end()) {
        it = groupOf.emplace(key, int32_t(snap->groups.size())).first;
        snap->groups.emplace_back(s.a == 0 ? kExteriorLabel : vol.userLabel[s.a], vol.userLabel[s.b]);
      }
      const Vec3 p = input.canonicalToPhysical(cpos[i]);
      snap->points.push_back({float(p[0]), float(p[1]), float(p[2])});
      snap->pointGroup.push_back(it->second);
    }
    ctx.preview(snap, true);
  }
  ctx.progress(1.0);
  return out;
}

ReportCounts reportCounts(const SurfaceSamples& s) {
  return {{"isosurface_triangles", double(s.isosurfaceTriangles)},
          {"interface_candidates", double(s.all.size())},
          {"surface_samples", double(s.selected.size())}};
}

}  // namespace femesher
