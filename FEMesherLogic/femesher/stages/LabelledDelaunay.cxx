// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/Parallel.h>
#include <femesher/RunContext.h>
#include <femesher/SpatialHash.h>
#include <femesher/stages/IndicatorFunctions.h>
#include <femesher/stages/LabelledDelaunay.h>
#include <femesher/stages/internal/LabelledDelaunayImpl.h>
#include <femesher/stages/internal/SpatialOrder.h>

#include <algorithm>
#include <unordered_map>

namespace femesher {

using internal::Delaunay;
using internal::Point;

LabelledDelaunay::LabelledDelaunay(int labels) : impl(std::make_unique<Impl>()) {
  impl->labels = labels;
}

LabelledDelaunay::~LabelledDelaunay() = default;

void LabelledDelaunay::insert(const std::vector<Vec3>& points) {
  std::vector<std::pair<Point, int32_t>> pts;
  pts.reserve(points.size());
  for (const Vec3& c : points) pts.emplace_back(Point(c[0], c[1], c[2]), int32_t(pts.size()));
  // CGAL's spatial sort shuffles with a global random generator; reseed it so that the same
  // input always gives the same triangulation (cospherical samples are common on a grid).
  CGAL::get_default_random() = CGAL::Random(12345);
  impl->dt.insert(pts.begin(), pts.end());
}

void LabelledDelaunay::insertRepairPoints(const std::vector<Vec3>& points) {
  Delaunay& dt = impl->dt;
  for (const Vec3& c : points) {
    const size_t before = dt.number_of_vertices();
    auto v = dt.insert(Point(c[0], c[1], c[2]));
    if (dt.number_of_vertices() > before) v->info() = internal::kRepairPoint;
  }
}

void LabelledDelaunay::label(const IndicatorField& field, RunContext& ctx) {
  Delaunay& dt = impl->dt;
  std::vector<Delaunay::Cell_handle> cells;
  cells.reserve(dt.number_of_cells());
  for (auto c = dt.all_cells_begin(); c != dt.all_cells_end(); ++c) cells.push_back(c);
  parallelFor(cells.size(), resolveThreads(ctx.threads()), [&](size_t b, size_t e, int) {
    for (size_t i = b; i < e; ++i) {
      if ((i & 0xFFFF) == 0 && ctx.isCanceled()) return;
      cells[i]->info() = internal::labelCell(field, dt, cells[i]);
    }
  });
  ctx.checkCancel();
}

bool LabelledDelaunay::forceLabelAt(const Vec3& c, int m) {
  auto cell = impl->dt.locate(Point(c[0], c[1], c[2]));
  if (impl->dt.is_infinite(cell)) return false;
  cell->info() = m;
  return true;
}

size_t LabelledDelaunay::vertexCount() const { return impl->dt.number_of_vertices(); }

size_t LabelledDelaunay::tetCount() const { return impl->dt.number_of_finite_cells(); }

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

std::vector<std::vector<Vec3>> LabelledDelaunay::enclosedHolePoints() const {
  std::vector<std::vector<Vec3>> holes;
  for (const auto& cavities : enclosedCavities()) {
    holes.emplace_back();
    for (const auto& candidates : cavities) holes.back().push_back(candidates.front());
  }
  return holes;
}

std::vector<std::vector<std::vector<Vec3>>> LabelledDelaunay::enclosedCavities(
    size_t candidates) const {
  Delaunay& dt = impl->dt;
  const int nLabels = impl->labels + 1;
  // Regions: connected sets of same-label cells (the infinite cells, label 0, join the outside).
  // Each cell's info holds its index while this runs (the labels are kept aside and restored).
  std::vector<Delaunay::Cell_handle> cells;
  cells.reserve(dt.number_of_cells());
  for (auto c = dt.all_cells_begin(); c != dt.all_cells_end(); ++c) cells.push_back(c);
  std::vector<int32_t> info(cells.size()), cellLabel(cells.size());
  for (size_t i = 0; i < cells.size(); ++i) {
    info[i] = cells[i]->info();
    cellLabel[i] = dt.is_infinite(cells[i]) ? 0 : info[i];
    cells[i]->info() = int32_t(i);
  }
  struct Restore {
    const std::vector<Delaunay::Cell_handle>& cells;
    const std::vector<int32_t>& info;
    ~Restore() {
      for (size_t i = 0; i < cells.size(); ++i) cells[i]->info() = info[i];
    }
  } restore{cells, info};
  auto indexOf = [](Delaunay::Cell_handle c) { return uint32_t(c->info()); };
  constexpr uint32_t kNone = ~0u;
  std::vector<uint32_t> region(cells.size(), kNone);
  std::vector<uint32_t> representative;  // a finite cell of the region, or kNone
  std::vector<int> regionLabel;
  std::vector<char> outside;
  std::vector<uint32_t> stack;
  for (size_t seed = 0; seed < cells.size(); ++seed) {
    if (region[seed] != kNone) continue;
    const uint32_t r = uint32_t(regionLabel.size());
    const int l = cellLabel[seed];
    regionLabel.push_back(l);
    representative.push_back(kNone);
    outside.push_back(0);
    region[seed] = r;
    stack.assign(1, uint32_t(seed));
    while (!stack.empty()) {
      const uint32_t ci = stack.back();
      stack.pop_back();
      const auto c = cells[ci];
      if (dt.is_infinite(c))
        outside[r] = 1;
      else if (representative[r] == kNone)
        representative[r] = ci;
      for (int k = 0; k < 4; ++k) {
        const auto n = c->neighbor(k);
        const uint32_t ni = indexOf(n);
        if (region[ni] != kNone || cellLabel[ni] != l) continue;
        region[ni] = r;
        stack.push_back(ni);
      }
    }
  }
  // Region adjacency (each pair once).
  std::vector<std::pair<uint32_t, uint32_t>> edges;
  for (size_t i = 0; i < cells.size(); ++i)
    for (int k = 0; k < 4; ++k) {
      const uint32_t j = indexOf(cells[i]->neighbor(k));
      if (region[i] < region[j]) edges.emplace_back(region[i], region[j]);
    }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  // Per label m: components of the other regions joined by their adjacencies; each component
  // that does not reach the outside is a cavity of m.
  std::vector<std::vector<std::vector<Vec3>>> holes(static_cast<size_t>(nLabels));
  std::vector<uint32_t> parent(regionLabel.size());
  auto centroidOf = [&](uint32_t ci) {
    const auto c = cells[ci];
    const Point g = CGAL::centroid(c->vertex(0)->point(), c->vertex(1)->point(),
                                   c->vertex(2)->point(), c->vertex(3)->point());
    return Vec3{g.x(), g.y(), g.z()};
  };
  // Largest volume first, ties by lower cell index (deterministic).
  auto larger = [](const std::pair<double, uint32_t>& a, const std::pair<double, uint32_t>& b) {
    return a.first != b.first ? a.first > b.first : a.second < b.second;
  };
  auto volumeOf = [&](uint32_t ci) {
    const auto c = cells[ci];
    return std::fabs(CGAL::volume(c->vertex(0)->point(), c->vertex(1)->point(),
                                  c->vertex(2)->point(), c->vertex(3)->point()));
  };
  auto find = [&](uint32_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  for (int m = 1; m < nLabels; ++m) {
    for (uint32_t r = 0; r < parent.size(); ++r) parent[r] = r;
    for (const auto& [a, b] : edges) {
      if (regionLabel[a] == m || regionLabel[b] == m) continue;
      uint32_t x = find(a), y = find(b);
      if (x == y) continue;
      if (y < x) std::swap(x, y);
      parent[y] = x;
    }
    std::vector<char> reaches(parent.size(), 0), touchesM(parent.size(), 0);
    for (uint32_t r = 0; r < parent.size(); ++r)
      if (regionLabel[r] != m && outside[r]) reaches[find(r)] = 1;
    for (const auto& [a, b] : edges) {  // only cavities that m's surface bounds matter
      if (regionLabel[a] == m && regionLabel[b] != m) touchesM[find(b)] = 1;
      if (regionLabel[b] == m && regionLabel[a] != m) touchesM[find(a)] = 1;
    }
    // Each enclosed component: first its root region's representative (the component's lowest
    // region id, a finite cell), then the centroids of its largest cells, largest first.
    std::vector<uint32_t> slot(parent.size(), kNone);
    std::vector<std::vector<std::pair<double, uint32_t>>> largest;
    for (uint32_t r = 0; r < parent.size(); ++r) {
      if (regionLabel[r] == m || find(r) != r || reaches[r] || !touchesM[r]) continue;
      slot[r] = uint32_t(holes[size_t(m)].size());
      holes[size_t(m)].push_back({centroidOf(representative[r])});
      largest.emplace_back();
    }
    if (candidates > 1 && !largest.empty()) {
      for (uint32_t ci = 0; ci < cells.size(); ++ci) {
        if (dt.is_infinite(cells[ci]) || cellLabel[ci] == m) continue;
        const uint32_t k = slot[find(region[ci])];
        if (k == kNone || ci == representative[find(region[ci])]) continue;
        auto& best = largest[k];
        best.emplace_back(volumeOf(ci), ci);
        if (best.size() > 4 * candidates) {  // keep the largest few
          std::sort(best.begin(), best.end(), larger);
          best.resize(candidates - 1);
        }
      }
      for (size_t k = 0; k < largest.size(); ++k) {
        auto& best = largest[k];
        std::sort(best.begin(), best.end(), larger);
        for (size_t q = 0; q < best.size() && q + 1 < candidates; ++q)
          holes[size_t(m)][k].push_back(centroidOf(best[q].second));
      }
    }
  }
  return holes;
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

void LabelledDelaunay::interfaceTriangles(std::vector<Vec3>& points,
                                          std::vector<std::array<int32_t, 3>>& triangles,
                                          std::vector<std::pair<uint16_t, uint16_t>>& pairs) const {
  const Delaunay& dt = impl->dt;
  points.clear();
  triangles.clear();
  pairs.clear();
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
    ids.emplace(&*v, int32_t(points.size()));
    points.push_back({v->point().x(), v->point().y(), v->point().z()});
  }
  std::vector<std::pair<std::array<int32_t, 5>, size_t>> order;  // (a, b, sorted ids), index
  for (size_t k = 0; k < raw.size(); ++k) {
    std::array<int32_t, 3> s{ids[&*raw[k].v[0]], ids[&*raw[k].v[1]], ids[&*raw[k].v[2]]};
    std::sort(s.begin(), s.end());
    order.push_back({{raw[k].a, raw[k].b, s[0], s[1], s[2]}, k});
  }
  std::sort(order.begin(), order.end());
  for (const auto& [key, k] : order) {
    triangles.push_back({ids[&*raw[k].v[0]], ids[&*raw[k].v[1]], ids[&*raw[k].v[2]]});
    pairs.emplace_back(raw[k].a, raw[k].b);
  }
}

namespace internal {

namespace {
/// A canonical point within 0.002 voxel of the input's box, put exactly on it (below every
/// projection tolerance; box faces become exactly planar, so no flat Delaunay tets lie on them).
Vec3 snapToBox(const IndicatorField& field, const Vec3& canonical) {  // unchanged when not snapped
  const PreprocessedVolume& vol = field.volume();
  const Vec3 l = vol.canonicalToLocal(canonical), q = field.snapToBox(l);
  return q == l ? canonical : vol.localToCanonical(q);
}

}  // namespace

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

std::vector<Delaunay::Vertex_handle> insertCandidates(const IndicatorField& field, Delaunay& dt,
                                                      std::vector<Candidate> cand, double cell,
                                                      int threads) {
  cand.erase(
      std::remove_if(cand.begin(), cand.end(), [](const Candidate& c) { return c.deviation == 0; }),
      cand.end());
  for (Candidate& c : cand) c.point = snapToBox(field, c.point);
  std::sort(cand.begin(), cand.end(), [](const Candidate& x, const Candidate& y) {
    if (x.deviation != y.deviation) return x.deviation > y.deviation;
    return x.point < y.point;
  });
  std::vector<Vec3> pts(cand.size());
  for (size_t i = 0; i < cand.size(); ++i) pts[i] = cand[i].point;
  const std::vector<uint32_t> spatial = mortonOrder(pts, cell);

  // 1. Too close to a vertex already there (read-only point location, in parallel).
  std::vector<char> nearVertex(cand.size(), 0);
  parallelFor(spatial.size(), threads, [&](size_t b, size_t e, int) {
    Delaunay::Cell_handle hint;
    for (size_t q = b; q < e; ++q) {
      const Candidate& c = cand[spatial[q]];
      const Point pt(c.point[0], c.point[1], c.point[2]);
      hint = dt.locate(pt, hint);
      const double ex2 = c.exclusion * c.exclusion;
      auto close = [&](Delaunay::Vertex_handle v) {
        return !dt.is_infinite(v) && CGAL::squared_distance(v->point(), pt) < ex2;
      };
      bool near = false;
      for (int k = 0; k < 4 && !near; ++k) {
        near = close(hint->vertex(k));
        const auto n = hint->neighbor(k);
        near = near || close(n->vertex(n->index(hint)));
      }
      nearVertex[spatial[q]] = near;
    }
  });
  // 2. Greedy among the candidates, largest deviation first.
  Vec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
  double maxExclusion = 0;
  for (const Candidate& c : cand) {
    maxExclusion = std::max(maxExclusion, c.exclusion);
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], c.point[a]);
      hi[a] = std::max(hi[a], c.point[a]);
    }
  }
  PointGrid grid(lo, hi, std::max(cell, 0.5 * maxExclusion), cand.size() / 4 + 1);
  std::vector<char> accepted(cand.size(), 0);
  for (size_t i = 0; i < cand.size(); ++i) {
    if (nearVertex[i]) continue;
    const Candidate& c = cand[i];
    bool close = false;
    grid.forEachNear(c.point, c.exclusion, [&](uint32_t j) {
      const Vec3& q = cand[j].point;
      const double dx = q[0] - c.point[0], dy = q[1] - c.point[1], dz = q[2] - c.point[2];
      close = close || dx * dx + dy * dy + dz * dz < c.exclusion * c.exclusion;
    });
    if (close) continue;
    accepted[i] = 1;
    grid.insert(uint32_t(i), c.point);
  }
  // 3. Insert in Z-order.
  std::vector<Delaunay::Vertex_handle> fresh;
  Delaunay::Cell_handle hint;
  for (uint32_t i : spatial) {
    if (!accepted[i]) continue;
    const Point pt(cand[i].point[0], cand[i].point[1], cand[i].point[2]);
    const size_t before = dt.number_of_vertices();
    auto v = dt.insert(pt, hint);
    hint = v->cell();
    if (dt.number_of_vertices() == before) continue;
    v->info() = kRefinementPoint;
    fresh.push_back(v);
  }
  return fresh;
}

void relabelAround(const IndicatorField& field, Delaunay& dt,
                   const std::vector<Delaunay::Vertex_handle>& fresh, int threads) {
  std::vector<Delaunay::Cell_handle> cells;
  for (auto v : fresh) dt.incident_cells(v, std::back_inserter(cells));
  std::sort(cells.begin(), cells.end());
  cells.erase(std::unique(cells.begin(), cells.end()), cells.end());
  parallelFor(cells.size(), threads, [&](size_t b, size_t e, int) {
    for (size_t i = b; i < e; ++i) cells[i]->info() = labelCell(field, dt, cells[i]);
  }, 64);  // per-cell results: the chunking changes nothing but the balance
}

}  // namespace internal

}  // namespace femesher
