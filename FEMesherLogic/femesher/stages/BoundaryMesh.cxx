// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/RunContext.h>
#include <femesher/Status.h>
#include <femesher/stages/BoundaryMesh.h>

#include <CGAL/Delaunay_triangulation_3.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_cell_base_with_info_3.h>
#include <CGAL/Triangulation_vertex_base_with_info_3.h>

#include <algorithm>
#include <random>
#include <unordered_map>

namespace femesher {

namespace {
using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Vb = CGAL::Triangulation_vertex_base_with_info_3<int32_t, K>;
using Cb = CGAL::Triangulation_cell_base_with_info_3<int32_t, K>;
using Tds = CGAL::Triangulation_data_structure_3<Vb, Cb>;
using Delaunay = CGAL::Delaunay_triangulation_3<K, Tds>;
using Point = K::Point_3;
}  // namespace

struct LabelledDelaunay::Impl {
  Delaunay dt;
  int labels = 0;
};

LabelledDelaunay::~LabelledDelaunay() = default;

int LabelledDelaunay::labelAt(const Vec3& c) const {
  const Delaunay& dt = impl->dt;
  Delaunay::Cell_handle ch = dt.locate(Point(c[0], c[1], c[2]));
  if (dt.is_infinite(ch)) return 0;
  return ch->info();
}

std::vector<size_t> LabelledDelaunay::tetsPerLabel() const {
  std::vector<size_t> n(size_t(impl->labels) + 1, 0);
  for (auto c = impl->dt.finite_cells_begin(); c != impl->dt.finite_cells_end(); ++c)
    ++n[size_t(c->info())];
  return n;
}

void LabelledDelaunay::adjacency(size_t n, std::vector<uint32_t>& offsets,
                                 std::vector<uint32_t>& neighbours) const {
  const Delaunay& dt = impl->dt;
  std::vector<std::vector<uint32_t>> adj(n);
  for (auto e = dt.finite_edges_begin(); e != dt.finite_edges_end(); ++e) {
    const int a = e->first->vertex(e->second)->info(), b = e->first->vertex(e->third)->info();
    if (a < 0 || b < 0 || size_t(a) >= n || size_t(b) >= n) continue;
    adj[size_t(a)].push_back(uint32_t(b));
    adj[size_t(b)].push_back(uint32_t(a));
  }
  offsets.assign(n + 1, 0);
  for (size_t i = 0; i < n; ++i) offsets[i + 1] = offsets[i] + uint32_t(adj[i].size());
  neighbours.clear();
  neighbours.reserve(offsets[n]);
  for (auto& a : adj) neighbours.insert(neighbours.end(), a.begin(), a.end());
}

void LabelledDelaunay::exportTets(std::vector<Vec3>& points,
                                  std::vector<std::array<int32_t, 4>>& tets,
                                  std::vector<int32_t>& labels) const {
  std::unordered_map<const void*, int32_t> ids;
  points.clear();
  tets.clear();
  labels.clear();
  for (auto c = impl->dt.finite_cells_begin(); c != impl->dt.finite_cells_end(); ++c) {
    if (c->info() == 0) continue;
    std::array<int32_t, 4> t;
    for (int i = 0; i < 4; ++i) {
      auto v = c->vertex(i);
      auto it = ids.find(&*v);
      if (it == ids.end()) {
        it = ids.emplace(&*v, int32_t(points.size())).first;
        points.push_back({v->point().x(), v->point().y(), v->point().z()});
      }
      t[i] = it->second;
    }
    tets.push_back(t);
    labels.push_back(c->info());
  }
}

namespace {

int labelCell(const IndicatorField& field, const Delaunay& dt, Delaunay::Cell_handle c) {
  if (dt.is_infinite(c)) return 0;
  const PreprocessedVolume& vol = field.volume();
  const Point& p0 = c->vertex(0)->point();
  const Point& p1 = c->vertex(1)->point();
  const Point& p2 = c->vertex(2)->point();
  const Point& p3 = c->vertex(3)->point();
  Vec3 pos;
  bool ok = false;
  if (!CGAL::coplanar(p0, p1, p2, p3)) {
    const Point cc = CGAL::circumcenter(p0, p1, p2, p3);
    pos = vol.canonicalToLocal({cc.x(), cc.y(), cc.z()});
    ok = pos[0] >= 0 && pos[1] >= 0 && pos[2] >= 0 && pos[0] <= vol.dims[0] - 1 &&
         pos[1] <= vol.dims[1] - 1 && pos[2] <= vol.dims[2] - 1;
  }
  if (!ok) {
    const Point g = CGAL::centroid(p0, p1, p2, p3);
    pos = vol.canonicalToLocal({g.x(), g.y(), g.z()});
  }
  return field.argmax(pos);
}

void labelAll(const IndicatorField& field, Delaunay& dt, RunContext& ctx) {
  size_t n = 0;
  for (auto c = dt.all_cells_begin(); c != dt.all_cells_end(); ++c) {
    c->info() = labelCell(field, dt, c);
    if ((++n & 0x3FFFF) == 0) ctx.checkCancel();
  }
}

}  // namespace

BoundarySurface buildBoundaryMesh(const IndicatorField& field, const std::vector<Vec3>& points,
                                  const SurfaceSamples& samples, RunContext& ctx) {
  const PreprocessedVolume& vol = field.volume();
  auto ld = std::make_shared<LabelledDelaunay>();
  ld->impl = std::make_unique<LabelledDelaunay::Impl>();
  ld->impl->labels = vol.materialCount();
  Delaunay& dt = ld->impl->dt;

  std::vector<std::pair<Point, int32_t>> pts;
  pts.reserve(points.size());
  for (const Vec3& l : points) {
    const Vec3 c = vol.localToCanonical(l);
    pts.emplace_back(Point(c[0], c[1], c[2]), int32_t(pts.size()));
  }
  if (pts.size() < 4) {
    // Tiny inputs: the sampling spacing exceeds the whole structure; use every interface vertex.
    pts.clear();
    for (const auto& smp : samples.all) {
      const Vec3 c = vol.localToCanonical(smp.local);
      pts.emplace_back(Point(c[0], c[1], c[2]), int32_t(pts.size()));
    }
  }
  if (pts.size() < 4)
    throw Error(ErrorCode::MeshingFailed,
                "Too few interface samples (" + std::to_string(pts.size()) +
                    ") to build a mesh: lower target_edge_length.");
  // CGAL's spatial sort shuffles with a global random generator; reseed it so that the same
  // input always gives the same triangulation (cospherical samples are common on a grid).
  CGAL::get_default_random() = CGAL::Random(12345);
  dt.insert(pts.begin(), pts.end());
  ctx.progress(0.4);
  labelAll(field, dt, ctx);
  ctx.progress(0.6);

  // Repair: labels that no tet carries.
  BoundarySurface out;
  for (int round = 0; round < 3; ++round) {
    const auto counts = ld->tetsPerLabel();
    std::vector<int> missing;
    for (int m = 1; m <= vol.materialCount(); ++m)
      if (counts[m] == 0 && vol.voxelCounts[m] > 0) missing.push_back(m);
    if (missing.empty()) break;
    std::vector<Point> extra;
    std::mt19937_64 rng(1234 + round);
    for (int m : missing) {
      out.repairedLabels.push_back(m);
      for (const auto& s : samples.all)
        if (s.a == m || s.b == m) {
          const Vec3 c = vol.localToCanonical(s.local);
          extra.emplace_back(c[0], c[1], c[2]);
        }
      std::vector<Point> centres;
      for (int k = 0; k < vol.dims[2]; ++k)
        for (int j = 0; j < vol.dims[1]; ++j)
          for (int i = 0; i < vol.dims[0]; ++i)
            if (vol.at(i, j, k) == m) {
              const Vec3 c = vol.localToCanonical({double(i), double(j), double(k)});
              centres.emplace_back(c[0], c[1], c[2]);
            }
      std::shuffle(centres.begin(), centres.end(), rng);
      if (centres.size() > 4000) centres.resize(4000);
      extra.insert(extra.end(), centres.begin(), centres.end());
    }
    for (const auto& p : extra) {
      const size_t before = dt.number_of_vertices();
      auto v = dt.insert(p);
      if (dt.number_of_vertices() > before) v->info() = -1;  // a repair point, not a particle
    }
    labelAll(field, dt, ctx);
  }
  // Last resort for a label that still has no tet (a feature far below the sampling, e.g. one
  // voxel): the Delaunay tets that contain its voxel centres take its label.
  {
    const auto counts = ld->tetsPerLabel();
    for (int m = 1; m <= vol.materialCount(); ++m) {
      if (counts[m] != 0 || vol.voxelCounts[m] == 0) continue;
      size_t forced = 0;
      for (int k = 0; k < vol.dims[2] && forced < 64; ++k)
        for (int j = 0; j < vol.dims[1] && forced < 64; ++j)
          for (int i = 0; i < vol.dims[0] && forced < 64; ++i)
            if (vol.at(i, j, k) == m) {
              const Vec3 c = vol.localToCanonical({double(i), double(j), double(k)});
              auto cell = dt.locate(Point(c[0], c[1], c[2]));
              if (!dt.is_infinite(cell)) {
                cell->info() = m;
                ++forced;
              }
            }
      if (forced) out.forcedLabels.push_back(m);
    }
  }
  ctx.progress(0.8);

  // Interface triangles. CGAL reports each facet from the cell with the smaller address, so the
  // raw order depends on the heap: orient every triangle from its lower-label cell and sort
  // vertices (by position) and triangles, so the same input always gives the same surface.
  struct RawTri {
    std::array<Delaunay::Vertex_handle, 3> v;
    uint16_t a, b;
  };
  std::vector<RawTri> raw;
  for (auto f = dt.finite_facets_begin(); f != dt.finite_facets_end(); ++f) {
    auto c = f->first;
    int i = f->second;
    auto n = c->neighbor(i);
    if (c->info() == n->info()) continue;
    if (c->info() > n->info()) {  // orient from the lower label's cell
      const int j = n->index(c);
      c = n;
      i = j;
    }
    RawTri t;
    // Outward orientation of facet i of cell c.
    t.v = {c->vertex((i + 1) % 4), c->vertex((i + 2) % 4), c->vertex((i + 3) % 4)};
    if (i % 2 == 1) std::swap(t.v[1], t.v[2]);
    t.a = uint16_t(c->info());
    t.b = uint16_t(c->neighbor(i)->info());
    raw.push_back(t);
  }
  std::vector<Delaunay::Vertex_handle> verts;
  for (const auto& t : raw) verts.insert(verts.end(), t.v.begin(), t.v.end());
  auto lessPoint = [](Delaunay::Vertex_handle x, Delaunay::Vertex_handle y) {
    const Point &p = x->point(), &q = y->point();
    if (p.x() != q.x()) return p.x() < q.x();
    if (p.y() != q.y()) return p.y() < q.y();
    return p.z() < q.z();
  };
  std::sort(verts.begin(), verts.end(), lessPoint);
  verts.erase(std::unique(verts.begin(), verts.end()), verts.end());
  std::unordered_map<const void*, int32_t> ids;
  for (auto v : verts) {
    ids.emplace(&*v, int32_t(out.points.size()));
    out.points.push_back({v->point().x(), v->point().y(), v->point().z()});
  }
  std::vector<std::pair<std::array<int32_t, 5>, size_t>> order;  // (a, b, sorted ids), index
  for (size_t k = 0; k < raw.size(); ++k) {
    std::array<int32_t, 3> s{ids[&*raw[k].v[0]], ids[&*raw[k].v[1]], ids[&*raw[k].v[2]]};
    std::sort(s.begin(), s.end());
    order.push_back({{raw[k].a, raw[k].b, s[0], s[1], s[2]}, k});
  }
  std::sort(order.begin(), order.end());
  for (const auto& [key, k] : order) {
    out.triangles.push_back({ids[&*raw[k].v[0]], ids[&*raw[k].v[1]], ids[&*raw[k].v[2]]});
    out.trianglePairs.emplace_back(raw[k].a, raw[k].b);
  }
  out.delaunayVertices = dt.number_of_vertices();
  out.delaunayTets = dt.number_of_finite_cells();
  out.delaunay = ld;
  ctx.progress(1.0);
  return out;
}

}  // namespace femesher
