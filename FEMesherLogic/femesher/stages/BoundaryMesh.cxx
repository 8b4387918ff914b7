// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/Parallel.h>
#include <femesher/RunContext.h>
#include <femesher/SpatialHash.h>
#include <femesher/Status.h>
#include <femesher/stages/BoundaryMesh.h>

#include <CGAL/Delaunay_triangulation_3.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_cell_base_with_info_3.h>
#include <CGAL/Triangulation_vertex_base_with_info_3.h>

#include <algorithm>
#include <chrono>
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

std::vector<std::vector<Vec3>> LabelledDelaunay::enclosedHolePoints() const {
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
      if (dt.is_infinite(c)) outside[r] = 1;
      else if (representative[r] == kNone) representative[r] = ci;
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
  std::vector<std::vector<Vec3>> holes(static_cast<size_t>(nLabels));
  std::vector<uint32_t> parent(regionLabel.size());
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
    for (uint32_t r = 0; r < parent.size(); ++r) {
      if (regionLabel[r] == m || find(r) != r || reaches[r] || !touchesM[r]) continue;
      // The root is the component's lowest region id; its representative is a finite cell.
      const auto c = cells[representative[r]];
      const Point g = CGAL::centroid(c->vertex(0)->point(), c->vertex(1)->point(),
                                     c->vertex(2)->point(), c->vertex(3)->point());
      holes[size_t(m)].push_back({g.x(), g.y(), g.z()});
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
  std::vector<Delaunay::Cell_handle> cells;
  cells.reserve(dt.number_of_cells());
  for (auto c = dt.all_cells_begin(); c != dt.all_cells_end(); ++c) cells.push_back(c);
  parallelFor(cells.size(), resolveThreads(ctx.threads()), [&](size_t b, size_t e, int) {
    for (size_t i = b; i < e; ++i) {
      if ((i & 0xFFFF) == 0 && ctx.isCanceled()) return;
      cells[i]->info() = labelCell(field, dt, cells[i]);
    }
  });
  ctx.checkCancel();
}

/// Surface refinement by facet distance (Boissonnat & Oudot's criterion, CGAL's
/// facet_distance): for every interface triangle (a, b), the interface f_a = f_b is searched along
/// the triangle's normal through its centroid; when it is farther than `delta` (mm), the crossing
/// is inserted as a new vertex. Candidates are taken farthest first, at most one per
/// neighbourhood of half the triangle's shortest edge and never closer than that to an existing
/// vertex, so the sampling stays well spaced. Rounds repeat until no triangle is off (or
/// kRounds). Returns the number of points inserted; their info is kRefinementPoint.
constexpr int32_t kRefinementPoint = -2;
constexpr int kRefineRounds = 10;

double secondsSince(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

/// A point to insert on an interface: how far off the surface was there (the order: farthest
/// first) and how close another vertex may be.
struct Candidate {
  double deviation;
  Vec3 point;
  double exclusion;
};

/// Indices of `points` in Z-order (Morton order on a grid of `cell`): neighbours in the list are
/// near in space, so walks from one to the next in the triangulation are short.
std::vector<uint32_t> mortonOrder(const std::vector<Vec3>& points, double cell) {
  Vec3 lo{1e300, 1e300, 1e300};
  for (const auto& p : points)
    for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], p[a]);
  auto spread = [](uint64_t x) {  // 21 bits -> every third bit
    x &= 0x1FFFFF;
    x = (x | x << 32) & 0x1F00000000FFFFull;
    x = (x | x << 16) & 0x1F0000FF0000FFull;
    x = (x | x << 8) & 0x100F00F00F00F00Full;
    x = (x | x << 4) & 0x10C30C30C30C30C3ull;
    x = (x | x << 2) & 0x1249249249249249ull;
    return x;
  };
  std::vector<std::pair<uint64_t, uint32_t>> keyed(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    uint64_t code = 0;
    for (int a = 0; a < 3; ++a)
      code |= spread(uint64_t(std::max(0.0, (points[i][a] - lo[a]) / cell))) << a;
    keyed[i] = {code, uint32_t(i)};
  }
  std::sort(keyed.begin(), keyed.end());
  std::vector<uint32_t> order(points.size());
  for (size_t i = 0; i < keyed.size(); ++i) order[i] = keyed[i].second;
  return order;
}

/// A canonical point within 0.002 voxel of the input's box, put exactly on it (below every
/// projection tolerance; box faces become exactly planar, so no flat Delaunay tets lie on them).
Vec3 snapToBox(const IndicatorField& field, const Vec3& canonical) {  // unchanged when not snapped
  const PreprocessedVolume& vol = field.volume();
  const Vec3 l = vol.canonicalToLocal(canonical), q = field.snapToBox(l);
  return q == l ? canonical : vol.localToCanonical(q);
}

/// Inserts the candidates with a non-zero deviation greedily, largest deviation first (ties by
/// position, so the order does not depend on threads): a candidate closer than its exclusion
/// radius to an already accepted candidate, or to a vertex of the triangulation's cell that
/// holds it or of that cell's neighbours, is skipped. The accepted ones go in in Z-order (short
/// walks). Returns the new vertices (info = kRefinementPoint).
std::vector<Delaunay::Vertex_handle> insertCandidates(const IndicatorField& field, Delaunay& dt,
                                                      std::vector<Candidate> cand, double cell,
                                                      int threads) {
  cand.erase(std::remove_if(cand.begin(), cand.end(),
                            [](const Candidate& c) { return c.deviation == 0; }),
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

/// Labels the cells created by inserting `fresh`: they are the cells incident to the new
/// vertices (a cell made by one insertion and destroyed by a later one is replaced by cells of
/// the later vertex).
void relabelAround(const IndicatorField& field, Delaunay& dt,
                   const std::vector<Delaunay::Vertex_handle>& fresh, int threads) {
  std::vector<Delaunay::Cell_handle> cells;
  for (auto v : fresh) dt.incident_cells(v, std::back_inserter(cells));
  std::sort(cells.begin(), cells.end());
  cells.erase(std::unique(cells.begin(), cells.end()), cells.end());
  parallelFor(cells.size(), threads, [&](size_t b, size_t e, int) {
    for (size_t i = b; i < e; ++i) cells[i]->info() = labelCell(field, dt, cells[i]);
  });
}

size_t refineFacetDistance(const IndicatorField& field, Delaunay& dt, double delta,
                           RunContext& ctx) {
  const PreprocessedVolume& vol = field.volume();
  const double smin = std::min({vol.spacing[0], vol.spacing[1], vol.spacing[2]});
  const int threads = resolveThreads(ctx.threads());
  size_t inserted = 0;
  struct Facet {
    std::array<Vec3, 3> p;
    int a, b;
  };
  // Round 0 looks at every interface facet; later rounds only at the facets of cells created by
  // the previous round's insertions (the cells incident to the new vertices), the rest did not
  // change.
  std::vector<Delaunay::Vertex_handle> fresh;
  auto addFacet = [](std::vector<Facet>& out, Delaunay::Cell_handle c, int i) {
    const auto n = c->neighbor(i);
    if (c->info() == n->info()) return;
    Facet x;
    x.a = std::min(c->info(), n->info());
    x.b = std::max(c->info(), n->info());
    for (int k = 0; k < 3; ++k) {
      const Point& q = c->vertex((i + 1 + k) % 4)->point();
      x.p[size_t(k)] = {q.x(), q.y(), q.z()};
    }
    // The same facet seen from either cell gives the same candidate to the last bit (the
    // arithmetic below depends on the vertex order).
    std::sort(x.p.begin(), x.p.end());
    out.push_back(x);
  };
  for (int round = 0; round < kRefineRounds; ++round) {
    const auto t0 = std::chrono::steady_clock::now();
    std::vector<Facet> facets;
    if (round == 0) {
      for (auto f = dt.finite_facets_begin(); f != dt.finite_facets_end(); ++f)
        addFacet(facets, f->first, f->second);
    } else {
      std::vector<Delaunay::Cell_handle> cells;
      for (auto v : fresh) dt.incident_cells(v, std::back_inserter(cells));
      std::sort(cells.begin(), cells.end());
      cells.erase(std::unique(cells.begin(), cells.end()), cells.end());
      std::vector<std::pair<std::array<Point, 3>, std::pair<Delaunay::Cell_handle, int>>> keyed;
      for (auto c : cells) {
        if (dt.is_infinite(c)) continue;
        for (int i = 0; i < 4; ++i) {
          if (dt.is_infinite(c->neighbor(i)) || c->info() == c->neighbor(i)->info()) continue;
          std::array<Point, 3> key{c->vertex((i + 1) % 4)->point(), c->vertex((i + 2) % 4)->point(),
                                   c->vertex((i + 3) % 4)->point()};
          std::sort(key.begin(), key.end());
          keyed.push_back({key, {c, i}});
        }
      }
      // Each facet once, in an order that does not depend on heap addresses.
      std::sort(keyed.begin(), keyed.end(),
                [](const auto& x, const auto& y) { return x.first < y.first; });
      for (size_t q = 0; q < keyed.size(); ++q)
        if (q == 0 || keyed[q].first != keyed[q - 1].first)
          addFacet(facets, keyed[q].second.first, keyed[q].second.second);
    }
    std::vector<Candidate> cand(facets.size(), Candidate{0, {0, 0, 0}, 0});
    parallelFor(facets.size(), threads, [&](size_t lo, size_t hi, int) {
      for (size_t i = lo; i < hi; ++i) {
        if ((i & 0xFFFF) == 0 && ctx.isCanceled()) return;
        const Facet& F = facets[i];
        Vec3 e[3], g{0, 0, 0};
        double minEdge = 1e300, maxEdge = 0;
        for (int k = 0; k < 3; ++k) {
          const Vec3 &u = F.p[size_t(k)], &v = F.p[size_t((k + 1) % 3)];
          e[k] = {v[0] - u[0], v[1] - u[1], v[2] - u[2]};
          const double l = std::sqrt(e[k][0] * e[k][0] + e[k][1] * e[k][1] + e[k][2] * e[k][2]);
          minEdge = std::min(minEdge, l);
          maxEdge = std::max(maxEdge, l);
          for (int a = 0; a < 3; ++a) g[a] += u[a] / 3.0;
        }
        Vec3 nrm{e[0][1] * e[1][2] - e[0][2] * e[1][1], e[0][2] * e[1][0] - e[0][0] * e[1][2],
                 e[0][0] * e[1][1] - e[0][1] * e[1][0]};
        const double nl = std::sqrt(nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]);
        if (!(nl > 0) || minEdge < 2 * delta) continue;
        for (auto& x : nrm) x /= nl;
        // The deviation is sampled at the centroid and at the three edge midpoints (a facet can
        // be close at its centroid and far along an edge); the farthest sample is the candidate.
        Vec3 samplesAt[4] = {g, {}, {}, {}};
        for (int k = 0; k < 3; ++k)
          for (int a = 0; a < 3; ++a)
            samplesAt[k + 1][a] = 0.5 * (F.p[size_t(k)][a] + F.p[size_t((k + 1) % 3)][a]);
        double bestDeviation = 0;
        Vec3 best{0, 0, 0};
        for (const Vec3& o : samplesAt) {
          auto phi = [&](double t) {
            const Vec3 l =
                vol.canonicalToLocal({o[0] + t * nrm[0], o[1] + t * nrm[1], o[2] + t * nrm[2]});
            return field.eval(F.a, l) - field.eval(F.b, l);
          };
          const double m = phi(-delta), p = phi(delta);
          if ((m <= 0) != (p <= 0)) continue;  // the interface crosses within +-delta
          // March outwards in both directions for the nearest crossing, then bisect.
          const double step = 0.25 * smin, reach = 0.75 * maxEdge;
          const double p0 = phi(0);
          double tIn = 0, tOut = 0;
          bool found = false;
          for (double t = step; t <= reach && !found; t += step)
            for (double sgn : {1.0, -1.0}) {
              const double v = phi(sgn * t);
              if ((v <= 0) != (p0 <= 0)) {
                tIn = sgn * (t - step);
                tOut = sgn * t;
                found = true;
                break;
              }
            }
          if (!found) continue;
          const double vIn = phi(tIn);
          for (int it = 0; it < 30; ++it) {
            const double mid = 0.5 * (tIn + tOut);
            if ((phi(mid) <= 0) == (vIn <= 0)) tIn = mid;
            else tOut = mid;
          }
          const double t = 0.5 * (tIn + tOut);
          if (std::fabs(t) <= std::max(delta, bestDeviation)) continue;
          const Vec3 q{o[0] + t * nrm[0], o[1] + t * nrm[1], o[2] + t * nrm[2]};
          // On the (a, b) interface, not in a third material.
          const int am = field.argmax(vol.canonicalToLocal(q));
          if (am != F.a && am != F.b) continue;
          bestDeviation = std::fabs(t);
          best = q;
        }
        if (bestDeviation == 0) continue;
        cand[i] = {bestDeviation, best, 0.5 * minEdge};
      }
    });
    ctx.checkCancel();
    const size_t tooFar = size_t(std::count_if(cand.begin(), cand.end(),
                                               [](const Candidate& c) { return c.deviation != 0; }));
    if (tooFar == 0) break;
    fresh = insertCandidates(field, dt, std::move(cand), smin, threads);
    const size_t roundInserted = fresh.size();
    inserted += roundInserted;
    ctx.debug("Facet-distance refinement round " + std::to_string(round) + ": " +
              std::to_string(facets.size()) + " facets checked, " + std::to_string(tooFar) +
              " too far, " + std::to_string(roundInserted) + " points inserted (" +
              std::to_string(secondsSince(t0)) + " s)");
    if (roundInserted == 0) break;
    relabelAround(field, dt, fresh, threads);
  }
  return inserted;
}

/// Voxel-centre refinement: every voxel centre next to another label must fall in a Delaunay tet
/// of its own label (the label map's own test of the mesh, and what Dice counts). A centre that
/// does not is projected onto the interface between its label and the label it fell in (Newton
/// on f_a - f_b; the smooth surfaces keep every centre on its side, so the projection is the
/// nearby surface point the sampling missed) and that point is inserted. Rounds repeat while
/// points go in (at most kRefineRounds).
size_t refineVoxelCentres(const IndicatorField& field, Delaunay& dt, RunContext& ctx) {
  const PreprocessedVolume& vol = field.volume();
  const double smin = std::min({vol.spacing[0], vol.spacing[1], vol.spacing[2]});
  const int threads = resolveThreads(ctx.threads());
  const auto& d = vol.dims;
  // Boundary voxels (a 6-neighbour of another label), found once.
  std::vector<std::vector<std::array<int, 3>>> perSlice(static_cast<size_t>(d[2]));
  parallelFor(size_t(d[2]), threads, [&](size_t z0, size_t z1, int) {
    for (size_t zz = z0; zz < z1; ++zz) {
      const int k = int(zz);
      for (int j = 0; j < d[1]; ++j)
        for (int i = 0; i < d[0]; ++i) {
          const uint16_t l = vol.at(i, j, k);
          bool edge = false;
          static const int o[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
          for (int q = 0; q < 6 && !edge; ++q) {
            const int x = i + o[q][0], y = j + o[q][1], z = k + o[q][2];
            if (x < 0 || y < 0 || z < 0 || x >= d[0] || y >= d[1] || z >= d[2]) continue;
            edge = vol.at(x, y, z) != l;
          }
          if (edge) perSlice[zz].push_back({i, j, k});
        }
    }
  });
  std::vector<std::array<int, 3>> voxels;
  for (auto& v : perSlice) voxels.insert(voxels.end(), v.begin(), v.end());
  perSlice.clear();
  size_t inserted = 0;
  const size_t allVoxels = voxels.size();
  std::vector<uint8_t> mark(vol.labels.size(), 0);
  for (int round = 0; round < kRefineRounds; ++round) {
    const auto t0 = std::chrono::steady_clock::now();
    std::vector<Candidate> cand(voxels.size(), Candidate{0, {0, 0, 0}, 0});
    std::vector<char> wrong(voxels.size(), 0);
    const int chunks = threads * 8;
    parallelFor(voxels.size(), threads, [&](size_t lo, size_t hi, int) {
      Delaunay::Cell_handle hint;
      for (size_t n = lo; n < hi; ++n) {
        if ((n & 0xFFFF) == 0 && ctx.isCanceled()) return;
        const auto [i, j, k] = voxels[n];
        const Vec3 c = vol.localToCanonical({double(i), double(j), double(k)});
        const Point pt(c[0], c[1], c[2]);
        hint = dt.locate(pt, hint);
        const int a = vol.at(i, j, k);
        const int b = dt.is_infinite(hint) ? 0 : hint->info();
        if (a == b) continue;
        wrong[n] = 1;
        // Newton from the centre onto f_a = f_b.
        Vec3 l{double(i), double(j), double(k)};
        bool ok = false;
        for (int it = 0; it < 20; ++it) {
          const double F = field.eval(a, l) - field.eval(b, l);
          if (std::fabs(F) < 1e-4 * smin) {
            ok = true;
            break;
          }
          const Vec3 ga = field.gradient(a, l), gb = field.gradient(b, l);
          const Vec3 g{(ga[0] - gb[0]) / vol.spacing[0], (ga[1] - gb[1]) / vol.spacing[1],
                       (ga[2] - gb[2]) / vol.spacing[2]};
          const double g2 = g[0] * g[0] + g[1] * g[1] + g[2] * g[2];
          if (g2 < 1e-20) break;
          Vec3 step{-F * g[0] / g2, -F * g[1] / g2, -F * g[2] / g2};
          const double len = std::sqrt(step[0] * step[0] + step[1] * step[1] + step[2] * step[2]);
          if (len > 0.5 * smin)
            for (auto& x : step) x *= 0.5 * smin / len;
          const Vec3 cc = vol.localToCanonical(l);
          l = vol.canonicalToLocal({cc[0] + step[0], cc[1] + step[1], cc[2] + step[2]});
        }
        if (!ok) continue;
        const int am = field.argmax(l);
        if (am != a && am != b) continue;
        const Vec3 q = vol.localToCanonical(l);
        const double dist = std::sqrt((q[0] - c[0]) * (q[0] - c[0]) + (q[1] - c[1]) * (q[1] - c[1]) +
                                      (q[2] - c[2]) * (q[2] - c[2]));
        if (dist > 2 * smin) continue;  // not the interface next to this voxel
        cand[n] = {1.0 / (1.0 + dist), q, 0.25 * smin};  // nearest surface points first
      }
    }, chunks);
    ctx.checkCancel();
    const size_t nWrong = size_t(std::count(wrong.begin(), wrong.end(), 1));
    const auto fresh = insertCandidates(field, dt, std::move(cand), smin, threads);
    ctx.debug("Voxel-centre refinement round " + std::to_string(round) + ": " +
              std::to_string(voxels.size()) + " of " + std::to_string(allVoxels) +
              " boundary voxels checked, " + std::to_string(nWrong) +
              " centres in a tet of another label, " + std::to_string(fresh.size()) +
              " points inserted (" + std::to_string(secondsSince(t0)) + " s)");
    inserted += fresh.size();
    relabelAround(field, dt, fresh, threads);
    // Stop when almost nothing could be inserted (the rest are centres whose surface point is
    // closer than a quarter voxel to a vertex already there).
    if (fresh.size() * 50 < nWrong || fresh.empty()) break;
    // Next round: the centres still wrong and those near a new point (only the cells around
    // new points changed label; a cell's circumsphere holds no other vertex, so a changed cell
    // lies within a few voxels of its new vertex at the sampling densities used here).
    std::fill(mark.begin(), mark.end(), 0);
    for (auto v : fresh) {
      const Vec3 l = vol.canonicalToLocal({v->point().x(), v->point().y(), v->point().z()});
      const int r = 3;
      for (int z = int(std::floor(l[2])) - r; z <= int(std::ceil(l[2])) + r; ++z)
        for (int y = int(std::floor(l[1])) - r; y <= int(std::ceil(l[1])) + r; ++y)
          for (int x = int(std::floor(l[0])) - r; x <= int(std::ceil(l[0])) + r; ++x)
            if (x >= 0 && y >= 0 && z >= 0 && x < d[0] && y < d[1] && z < d[2])
              mark[vol.index(x, y, z)] = 1;
    }
    std::vector<std::array<int, 3>> next;
    for (size_t n = 0; n < voxels.size(); ++n)
      if (wrong[n] || mark[vol.index(voxels[n][0], voxels[n][1], voxels[n][2])])
        next.push_back(voxels[n]);
    voxels.swap(next);
  }
  return inserted;
}

/// Junction refinement: a junction particle (triple line) must be a vertex of an edge around
/// which three or more materials meet, i.e. the line must appear as mesh edges. A junction particle
/// where it does not is handled by what its star (the Delaunay cells around it) lacks:
///  - a material of its junction has no cell there (the usual case on real data: near the line
///    that material is a wedge thinner than the sampling, e.g. the background cusp where two
///    cartilages touch, so no circumcentre of the cells around the particle falls in it). The
///    wedge is found on small spheres around the particle (the radius halved, from one voxel in
///    the first round and half as much in each later round, down to a sixteenth of a voxel, until
///    the material covers a tenth of the sphere); the two interfaces bounding it there (the
///    missing material against each of the other two) get a point each, and the line gets the
///    points about that far from the particle on either side. The Voronoi edge dual to the
///    triangle of the particle and the two wedge points runs along the line, between the
///    circumcentres of the cells it makes with the two line points: both lie in the wedge, so
///    the star holds the material, and the edges to the line points have all three around them.
///  - all three are there but on no common edge: the line points about the round's radius from
///    it on either side are inserted (else, when they cannot be located, the located line point
///    of `Junctions::candidates` nearest to the midpoint between the particle and its nearest
///    neighbour on the same line, if at least a fifth of their distance from both).
/// Up to kRefineRounds rounds. `jv[j]` is junction particle j's vertex.
size_t refineJunctionEdges(const IndicatorField& field, Delaunay& dt, const Junctions& junctions,
                           const std::vector<Delaunay::Vertex_handle>& jv, RunContext& ctx,
                           size_t& stillOff) {
  const PreprocessedVolume& vol = field.volume();
  const int threads = resolveThreads(ctx.threads());
  auto keyOf = [](const JunctionPoint& p) {
    uint64_t k = p.count;
    for (int i = 0; i < p.count; ++i) k = (k << 16) | p.labels[size_t(i)];
    return k;
  };
  // Located line points and junction particles, grouped by label set.
  std::unordered_map<uint64_t, std::vector<Vec3>> linePoints;
  for (const auto& c : junctions.candidates)
    if (c.count == 3) linePoints[keyOf(c)].push_back(vol.localToCanonical(c.local));
  std::unordered_map<uint64_t, std::vector<uint32_t>> members;
  for (size_t j = 0; j < jv.size(); ++j)
    if (jv[j] != Delaunay::Vertex_handle() && junctions.particles[j].count == 3)
      members[keyOf(junctions.particles[j])].push_back(uint32_t(j));
  auto onTripleEdge = [&](Delaunay::Vertex_handle v) {
    std::vector<Delaunay::Edge> edges;
    dt.finite_incident_edges(v, std::back_inserter(edges));
    for (const auto& e : edges) {
      int labels[3], n = 0;
      auto c = dt.incident_cells(e), done = c;
      do {
        const int l = dt.is_infinite(c) ? 0 : c->info();
        bool seen = false;
        for (int i = 0; i < n; ++i) seen |= labels[i] == l;
        if (!seen) {
          labels[n++] = l;
          if (n == 3) return true;
        }
      } while (++c != done);
    }
    return false;
  };
  auto pointOf = [](Delaunay::Vertex_handle v) {
    return Vec3{v->point().x(), v->point().y(), v->point().z()};
  };
  auto dist2 = [](const Vec3& a, const Vec3& b) {
    return (a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]);
  };
  const double smin = std::min({vol.spacing[0], vol.spacing[1], vol.spacing[2]});
  // Directions for finding a material's wedge around a particle (Fibonacci lattice on the sphere).
  constexpr int kWedgeDirections = 64;
  std::vector<Vec3> dirs(kWedgeDirections);
  for (int i = 0; i < kWedgeDirections; ++i) {
    const double z = 1.0 - (2.0 * i + 1.0) / kWedgeDirections, r = std::sqrt(1.0 - z * z);
    const double phi = i * 2.399963229728653;  // golden angle
    dirs[size_t(i)] = {r * std::cos(phi), r * std::sin(phi), z};
  }
  // The points of the particle's triple line about r from it on either side (canonical mm; none
  // at a quadruple point).
  auto nearLinePoints = [&](const Vec3& p, const JunctionPoint& jp, double r, Candidate* out) {
    int written = 0;
    if (jp.count != 3) return written;
    const Vec3 pl = vol.canonicalToLocal(p);
    Vec3 g[2];
    for (int i = 0; i < 2; ++i) {
      const Vec3 g0 = field.gradient(jp.labels[0], pl),
                 gi = field.gradient(jp.labels[size_t(i + 1)], pl);
      g[i] = {(g0[0] - gi[0]) / vol.spacing[0], (g0[1] - gi[1]) / vol.spacing[1],
              (g0[2] - gi[2]) / vol.spacing[2]};
    }
    const Vec3 t{g[0][1] * g[1][2] - g[0][2] * g[1][1], g[0][2] * g[1][0] - g[0][0] * g[1][2],
                 g[0][0] * g[1][1] - g[0][1] * g[1][0]};
    const double tl = std::sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
    if (!(tl > 0)) return written;
    for (double sgn : {1.0, -1.0}) {
      Vec3 x = vol.canonicalToLocal(
          {p[0] + sgn * r * t[0] / tl, p[1] + sgn * r * t[1] / tl, p[2] + sgn * r * t[2] / tl});
      if (!locateJunctionPoint(field, jp.labels.data(), 3, x)) continue;
      const Vec3 q = vol.localToCanonical(x);
      const double d2 = dist2(q, p);
      if (d2 < 0.25 * r * r || d2 > 4 * r * r) continue;
      out[written++] = {1.0 + r, q, 0.25 * r};
    }
    return written;
  };
  // The two (or, at a quadruple point, up to three) interface points bounding the wedge of
  // material c next to the particle at p (canonical mm), and the line points as far on either
  // side. The radius goes from r0 down to a sixteenth of a voxel until c covers at least a tenth
  // of the sphere (a wedge of 36 degrees or more), so the points are neither in the thin part of
  // the wedge nor crowded onto the particle (never closer than a quarter of the radius to it or
  // to another vertex).
  auto wedgePoints = [&](const Vec3& p, int c, const JunctionPoint& jp, double r0, Candidate* out) {
    int written = 0;
    for (double r = r0; r > 0.05 * smin; r *= 0.5) {
      Vec3 sum{0, 0, 0};
      int hits = 0;
      for (const Vec3& u : dirs)
        if (field.argmax(
                vol.canonicalToLocal({p[0] + r * u[0], p[1] + r * u[1], p[2] + r * u[2]})) == c) {
          for (int a = 0; a < 3; ++a) sum[a] += u[a];
          ++hits;
        }
      if (hits * 10 < kWedgeDirections) continue;
      const double sl = std::sqrt(sum[0] * sum[0] + sum[1] * sum[1] + sum[2] * sum[2]);
      if (!(sl > 0)) continue;
      const Vec3 m{p[0] + r * sum[0] / sl, p[1] + r * sum[1] / sl, p[2] + r * sum[2] / sl};
      if (field.argmax(vol.canonicalToLocal(m)) != c) continue;
      for (int i = 0; i < jp.count; ++i) {
        const int o = jp.labels[size_t(i)];
        if (o == c) continue;
        // Along the gradient of f_o - f_c from m (inside c) to where o takes over.
        const Vec3 ml = vol.canonicalToLocal(m);
        const Vec3 go = field.gradient(o, ml), gc = field.gradient(c, ml);
        Vec3 g{(go[0] - gc[0]) / vol.spacing[0], (go[1] - gc[1]) / vol.spacing[1],
               (go[2] - gc[2]) / vol.spacing[2]};
        const double gl = std::sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
        if (!(gl > 0)) continue;
        for (auto& x : g) x /= gl;
        auto phi = [&](double t) {
          const Vec3 l = vol.canonicalToLocal({m[0] + t * g[0], m[1] + t * g[1], m[2] + t * g[2]});
          return field.eval(o, l) - field.eval(c, l);
        };
        double tIn = 0, tOut = -1;
        for (double t = 0.125 * r; t <= 2 * r; t += 0.125 * r) {
          if (phi(t) >= 0) {
            tOut = t;
            break;
          }
          tIn = t;
        }
        if (tOut < 0) continue;
        for (int it = 0; it < 30; ++it) {
          const double mid = 0.5 * (tIn + tOut);
          if (phi(mid) < 0)
            tIn = mid;
          else
            tOut = mid;
        }
        const double t = 0.5 * (tIn + tOut);
        const Vec3 w{m[0] + t * g[0], m[1] + t * g[1], m[2] + t * g[2]};
        const int am = field.argmax(vol.canonicalToLocal(w));
        if (am != o && am != c) continue;  // another material's interface
        if (dist2(w, p) < 0.0625 * r * r) continue;
        out[written++] = {1.0 + r, w, 0.25 * r};
      }
      if (written > 0) written += nearLinePoints(p, jp, r, out + written);
      break;
    }
    return written;
  };
  constexpr int kPerParticle = 16;  // up to 4 missing materials x 3 others, 2 line points each
  size_t inserted = 0;
  stillOff = 0;
  for (int round = 0; round < kRefineRounds; ++round) {
    std::vector<uint32_t> off;
    std::vector<uint8_t> missing;  // per off particle: bit i = labels[i] has no cell around it
    for (size_t j = 0; j < jv.size(); ++j) {
      if (jv[j] == Delaunay::Vertex_handle() || onTripleEdge(jv[j])) continue;
      const JunctionPoint& jp = junctions.particles[j];
      std::vector<Delaunay::Cell_handle> cells;  // (incident_cells is not thread safe)
      dt.incident_cells(jv[j], std::back_inserter(cells));
      uint8_t miss = 0;
      for (int i = 0; i < jp.count; ++i) {
        bool there = false;
        for (auto c : cells)
          there = there || (dt.is_infinite(c) ? 0 : c->info()) == jp.labels[size_t(i)];
        if (!there) miss |= uint8_t(1u << i);
      }
      off.push_back(uint32_t(j));
      missing.push_back(miss);
    }
    stillOff = off.size();
    if (off.empty()) break;
    std::vector<Candidate> cand(off.size() * kPerParticle, Candidate{0, {0, 0, 0}, 0});
    // Each round looks for the wedges closer to the particles (where they are wider).
    const double wedgeRadius = std::ldexp(smin, -round);
    parallelFor(off.size(), threads, [&](size_t b, size_t e, int) {
      for (size_t n = b; n < e; ++n) {
        const uint32_t j = off[n];
        const JunctionPoint& jp = junctions.particles[j];
        const Vec3 p = pointOf(jv[j]);
        if (missing[n]) {
          int w = 0;
          for (int i = 0; i < jp.count; ++i)
            if (missing[n] & (1u << i))
              w += wedgePoints(p, jp.labels[size_t(i)], jp, wedgeRadius,
                               &cand[n * kPerParticle + size_t(w)]);
          continue;
        }
        if (jp.count != 3) continue;
        // All its materials are around it but on no common edge: the line points about the
        // round's radius from it on either side (the triple edges are the ones along the line),
        // else the located line point halfway to its neighbour on the line.
        if (nearLinePoints(p, jp, wedgeRadius, &cand[n * kPerParticle]) > 0) continue;
        const uint64_t key = keyOf(jp);
        // Nearest other particle of the same line.
        double best = 1e300;
        Vec3 q{0, 0, 0};
        for (uint32_t k : members.at(key)) {
          if (k == j) continue;
          const double d2 = dist2(p, pointOf(jv[k]));
          if (d2 < best) {
            best = d2;
            q = pointOf(jv[k]);
          }
        }
        if (best >= 1e300) continue;
        const double d = std::sqrt(best);
        const Vec3 m{0.5 * (p[0] + q[0]), 0.5 * (p[1] + q[1]), 0.5 * (p[2] + q[2])};
        double bestM = 0.25 * best;  // within half of d of the midpoint
        const Vec3* pick = nullptr;
        const auto it = linePoints.find(key);
        if (it == linePoints.end()) continue;
        for (const Vec3& c : it->second) {
          const double dm = dist2(c, m);
          if (dm >= bestM) continue;
          if (dist2(c, p) < 0.04 * best || dist2(c, q) < 0.04 * best) continue;
          bestM = dm;
          pick = &c;
        }
        if (pick) cand[n * kPerParticle] = {1.0 / (1.0 + d), *pick, 0.2 * d};
      }
    });
    ctx.checkCancel();
    const auto fresh = insertCandidates(field, dt, std::move(cand), smin, threads);
    ctx.debug("Junction refinement round " + std::to_string(round) + ": " +
              std::to_string(off.size()) + " junction particles not on a triple edge (" +
              std::to_string(
                  std::count_if(missing.begin(), missing.end(), [](uint8_t m) { return m != 0; })) +
              " with a material missing around them), " + std::to_string(fresh.size()) +
              " points inserted");
    inserted += fresh.size();
    if (fresh.empty()) break;
    relabelAround(field, dt, fresh, threads);
  }
  return inserted;
}

}  // namespace

BoundarySurface buildBoundaryMesh(const IndicatorField& field, const std::vector<Vec3>& points,
                                  const SurfaceSamples& samples, RunContext& ctx,
                                  double facetDistance, const Junctions* junctions,
                                  bool voxelRefinement) {
  const PreprocessedVolume& vol = field.volume();
  auto ld = std::make_shared<LabelledDelaunay>();
  ld->impl = std::make_unique<LabelledDelaunay::Impl>();
  ld->impl->labels = vol.materialCount();
  Delaunay& dt = ld->impl->dt;

  std::vector<std::pair<Point, int32_t>> pts;
  pts.reserve(points.size());
  for (const Vec3& l : points) {
    const Vec3 c = vol.localToCanonical(field.snapToBox(l));
    pts.emplace_back(Point(c[0], c[1], c[2]), int32_t(pts.size()));
  }
  const bool particlesAreVertices = pts.size() >= 4;
  if (pts.size() < 4) {
    // Tiny inputs: the sampling spacing exceeds the whole structure; use every interface vertex.
    pts.clear();
    for (const auto& smp : samples.all) {
      const Vec3 c = vol.localToCanonical(field.snapToBox(smp.local));
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
  ctx.progress(0.5);
  BoundarySurface out;
  if (facetDistance > 0) {
    out.refinementPoints = refineFacetDistance(field, dt, facetDistance, ctx);
    if (voxelRefinement) out.voxelCentrePoints = refineVoxelCentres(field, dt, ctx);
  }
  if (junctions && !junctions->particles.empty() && facetDistance > 0 && particlesAreVertices &&
      points.size() >= junctions->particles.size()) {
    std::vector<Delaunay::Vertex_handle> jv(junctions->particles.size());
    for (auto v = dt.finite_vertices_begin(); v != dt.finite_vertices_end(); ++v)
      if (v->info() >= 0 && size_t(v->info()) < jv.size()) jv[size_t(v->info())] = v;
    out.junctionPoints = refineJunctionEdges(field, dt, *junctions, jv, ctx, out.junctionsOffLines);
  }
  ctx.progress(0.6);

  // Repair: labels that no tet carries.
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
