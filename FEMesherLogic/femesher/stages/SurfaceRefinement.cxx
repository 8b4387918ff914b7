// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/Parallel.h>
#include <femesher/RunContext.h>
#include <femesher/VecMath.h>
#include <femesher/stages/IndicatorFunctions.h>
#include <femesher/stages/Junctions.h>
#include <femesher/stages/LabelledDelaunay.h>
#include <femesher/stages/SurfaceRefinement.h>
#include <femesher/stages/internal/LabelledDelaunayImpl.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <unordered_map>

namespace femesher {

using internal::Candidate;
using internal::Delaunay;
using internal::insertCandidates;
using internal::Point;
using internal::relabelAround;

namespace {

constexpr int kRefineRounds = 10;

double secondsSince(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

Vec3 pointOf(Delaunay::Vertex_handle v) {
  return Vec3{v->point().x(), v->point().y(), v->point().z()};
}

double dist2(const Vec3& a, const Vec3& b) {
  return (a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
         (a[2] - b[2]) * (a[2] - b[2]);
}

/// Key of a junction's label set (its count and labels).
uint64_t keyOf(const JunctionPoint& p) {
  uint64_t k = p.count;
  for (int i = 0; i < p.count; ++i) k = (k << 16) | p.labels[size_t(i)];
  return k;
}

/// The junction refinement of refineJunctionEdges (SurfaceRefinement.h), round by round. Each
/// round the particles on no triple edge are found (serially: CGAL's incident_cells is not
/// thread safe), their candidates computed in parallel (up to kPerParticle each) and inserted.
/// Where a material is missing around a particle, the wedge points and the line points next to
/// them make the Voronoi edge dual to the triangle of the particle and the two wedge points run
/// along the line, between circumcentres that lie in the wedge: the star then holds the material,
/// and the edges to the line points have all three around them.
class JunctionRefiner {
 public:
  JunctionRefiner(const IndicatorField& field, Delaunay& dt, const Junctions& junctions,
                  RunContext& ctx);
  JunctionRefinement run();

 private:
  /// Up to 4 missing materials x 3 others, 2 line points each.
  static constexpr int kPerParticle = 16;
  /// Directions for finding a material's wedge around a particle (Fibonacci lattice).
  static constexpr int kWedgeDirections = 64;

  bool onTripleEdge(Delaunay::Vertex_handle v) const;
  /// The junction particles on no triple edge (indices), and per particle the bit set of its
  /// labels (bit i = labels[i]) that no cell around it carries.
  void offParticles(std::vector<uint32_t>& off, std::vector<uint8_t>& missing) const;
  int nearLinePoints(const Vec3& p, const JunctionPoint& jp, double r, Candidate* out) const;
  int wedgePoints(const Vec3& p, int c, const JunctionPoint& jp, double r0, Candidate* out) const;
  /// The located line point nearest to the midpoint between particle j (at p) and its nearest
  /// neighbour on the same line (one candidate, or none).
  void lineMidpoint(uint32_t j, const Vec3& p, const JunctionPoint& jp, Candidate* out) const;

  const IndicatorField& field_;
  const PreprocessedVolume& vol_;
  Delaunay& dt_;
  const Junctions& junctions_;
  RunContext& ctx_;
  const int threads_;
  const double smin_;
  std::vector<Delaunay::Vertex_handle> jv_;  ///< junction particle j's vertex (or none)
  std::vector<Vec3> dirs_;
  /// Located line points and junction particles, grouped by label set.
  std::unordered_map<uint64_t, std::vector<Vec3>> linePoints_;
  std::unordered_map<uint64_t, std::vector<uint32_t>> members_;
};

JunctionRefiner::JunctionRefiner(const IndicatorField& field, Delaunay& dt,
                                 const Junctions& junctions, RunContext& ctx)
    : field_(field),
      vol_(field.volume()),
      dt_(dt),
      junctions_(junctions),
      ctx_(ctx),
      threads_(resolveThreads(ctx.threads())),
      smin_(std::min({vol_.spacing[0], vol_.spacing[1], vol_.spacing[2]})),
      jv_(junctions.particles.size()),
      dirs_(kWedgeDirections) {
  for (auto v = dt.finite_vertices_begin(); v != dt.finite_vertices_end(); ++v)
    if (v->info() >= 0 && size_t(v->info()) < jv_.size()) jv_[size_t(v->info())] = v;
  for (const auto& c : junctions.candidates)
    if (c.count == 3) linePoints_[keyOf(c)].push_back(vol_.localToCanonical(c.local));
  for (size_t j = 0; j < jv_.size(); ++j)
    if (jv_[j] != Delaunay::Vertex_handle() && junctions.particles[j].count == 3)
      members_[keyOf(junctions.particles[j])].push_back(uint32_t(j));
  for (int i = 0; i < kWedgeDirections; ++i) {
    const double z = 1.0 - (2.0 * i + 1.0) / kWedgeDirections, r = std::sqrt(1.0 - z * z);
    const double phi = i * 2.399963229728653;  // golden angle
    dirs_[size_t(i)] = {r * std::cos(phi), r * std::sin(phi), z};
  }
}

bool JunctionRefiner::onTripleEdge(Delaunay::Vertex_handle v) const {
  std::vector<Delaunay::Edge> edges;
  dt_.finite_incident_edges(v, std::back_inserter(edges));
  for (const auto& e : edges) {
    int labels[3], n = 0;
    auto c = dt_.incident_cells(e), done = c;
    do {
      const int l = dt_.is_infinite(c) ? 0 : c->info();
      bool seen = false;
      for (int i = 0; i < n; ++i) seen |= labels[i] == l;
      if (!seen) {
        labels[n++] = l;
        if (n == 3) return true;
      }
    } while (++c != done);
  }
  return false;
}

void JunctionRefiner::offParticles(std::vector<uint32_t>& off,
                                   std::vector<uint8_t>& missing) const {
  for (size_t j = 0; j < jv_.size(); ++j) {
    if (jv_[j] == Delaunay::Vertex_handle() || onTripleEdge(jv_[j])) continue;
    const JunctionPoint& jp = junctions_.particles[j];
    std::vector<Delaunay::Cell_handle> cells;
    dt_.incident_cells(jv_[j], std::back_inserter(cells));
    uint8_t miss = 0;
    for (int i = 0; i < jp.count; ++i) {
      bool there = false;
      for (auto c : cells)
        there = there || (dt_.is_infinite(c) ? 0 : c->info()) == jp.labels[size_t(i)];
      if (!there) miss |= uint8_t(1u << i);
    }
    off.push_back(uint32_t(j));
    missing.push_back(miss);
  }
}

/// The points of the particle's triple line about r from it on either side (canonical mm; none
/// at a quadruple point).
int JunctionRefiner::nearLinePoints(const Vec3& p, const JunctionPoint& jp, double r,
                                    Candidate* out) const {
  int written = 0;
  if (jp.count != 3) return written;
  const Vec3 pl = vol_.canonicalToLocal(p);
  Vec3 g[2];
  for (int i = 0; i < 2; ++i) {
    const Vec3 g0 = field_.gradient(jp.labels[0], pl),
               gi = field_.gradient(jp.labels[size_t(i + 1)], pl);
    g[i] = {(g0[0] - gi[0]) / vol_.spacing[0], (g0[1] - gi[1]) / vol_.spacing[1],
            (g0[2] - gi[2]) / vol_.spacing[2]};
  }
  const Vec3 t{g[0][1] * g[1][2] - g[0][2] * g[1][1], g[0][2] * g[1][0] - g[0][0] * g[1][2],
               g[0][0] * g[1][1] - g[0][1] * g[1][0]};
  const double tl = std::sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
  if (!(tl > 0)) return written;
  for (double sgn : {1.0, -1.0}) {
    Vec3 x = vol_.canonicalToLocal(
        {p[0] + sgn * r * t[0] / tl, p[1] + sgn * r * t[1] / tl, p[2] + sgn * r * t[2] / tl});
    if (!locateJunctionPoint(field_, jp.labels.data(), 3, x)) continue;
    const Vec3 q = vol_.localToCanonical(x);
    const double d2 = dist2(q, p);
    if (d2 < 0.25 * r * r || d2 > 4 * r * r) continue;
    out[written++] = {1.0 + r, q, 0.25 * r};
  }
  return written;
}

/// The two (or, at a quadruple point, up to three) interface points bounding the wedge of
/// material c next to the particle at p (canonical mm), and the line points as far on either
/// side. The radius goes from r0 down to a sixteenth of a voxel until c covers at least a tenth
/// of the sphere (a wedge of 36 degrees or more), so the points are neither in the thin part of
/// the wedge nor crowded onto the particle (never closer than a quarter of the radius to it or
/// to another vertex).
int JunctionRefiner::wedgePoints(const Vec3& p, int c, const JunctionPoint& jp, double r0,
                                 Candidate* out) const {
  const PreprocessedVolume& vol = vol_;
  const IndicatorField& field = field_;
  int written = 0;
  for (double r = r0; r > 0.05 * smin_; r *= 0.5) {
    Vec3 sum{0, 0, 0};
    int hits = 0;
    for (const Vec3& u : dirs_)
      if (field.argmax(vol.canonicalToLocal({p[0] + r * u[0], p[1] + r * u[1], p[2] + r * u[2]})) ==
          c) {
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
}

void JunctionRefiner::lineMidpoint(uint32_t j, const Vec3& p, const JunctionPoint& jp,
                                   Candidate* out) const {
  const uint64_t key = keyOf(jp);
  // Nearest other particle of the same line.
  double best = 1e300;
  Vec3 q{0, 0, 0};
  for (uint32_t k : members_.at(key)) {
    if (k == j) continue;
    const double d2 = dist2(p, pointOf(jv_[k]));
    if (d2 < best) {
      best = d2;
      q = pointOf(jv_[k]);
    }
  }
  if (best >= 1e300) return;
  const double d = std::sqrt(best);
  const Vec3 m{0.5 * (p[0] + q[0]), 0.5 * (p[1] + q[1]), 0.5 * (p[2] + q[2])};
  double bestM = 0.25 * best;  // within half of d of the midpoint
  const Vec3* pick = nullptr;
  const auto it = linePoints_.find(key);
  if (it == linePoints_.end()) return;
  for (const Vec3& c : it->second) {
    const double dm = dist2(c, m);
    if (dm >= bestM) continue;
    if (dist2(c, p) < 0.04 * best || dist2(c, q) < 0.04 * best) continue;
    bestM = dm;
    pick = &c;
  }
  if (pick) *out = {1.0 / (1.0 + d), *pick, 0.2 * d};
}

JunctionRefinement JunctionRefiner::run() {
  JunctionRefinement result;
  for (int round = 0; round < kRefineRounds; ++round) {
    std::vector<uint32_t> off;
    std::vector<uint8_t> missing;  // per off particle: bit i = labels[i] has no cell around it
    offParticles(off, missing);
    result.stillOff = off.size();
    if (off.empty()) break;
    std::vector<Candidate> cand(off.size() * kPerParticle, Candidate{0, {0, 0, 0}, 0});
    // Each round looks for the wedges closer to the particles (where they are wider).
    const double wedgeRadius = std::ldexp(smin_, -round);
    parallelFor(off.size(), threads_, [&](size_t b, size_t e, int) {
      for (size_t n = b; n < e; ++n) {
        const uint32_t j = off[n];
        const JunctionPoint& jp = junctions_.particles[j];
        const Vec3 p = pointOf(jv_[j]);
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
        lineMidpoint(j, p, jp, &cand[n * kPerParticle]);
      }
    });
    ctx_.checkCancel();
    const auto fresh = insertCandidates(field_, dt_, std::move(cand), smin_, threads_);
    ctx_.debug("Junction refinement round " + std::to_string(round) + ": " +
               std::to_string(off.size()) + " junction particles not on a triple edge (" +
               std::to_string(std::count_if(missing.begin(), missing.end(),
                                            [](uint8_t m) { return m != 0; })) +
               " with a material missing around them), " + std::to_string(fresh.size()) +
               " points inserted");
    result.inserted += fresh.size();
    if (fresh.empty()) break;
    relabelAround(field_, dt_, fresh, threads_);
  }
  return result;
}

}  // namespace

namespace {

/// An interface triangle of the labelled Delaunay: its corners (sorted, so the arithmetic on
/// them does not depend on which side it was seen from), its labels a < b, and one of its two
/// cells with the facet's index there.
struct InterfaceFacet {
  std::array<Vec3, 3> p;
  int a, b;
  Delaunay::Cell_handle cell;
  int index;
};

/// The rounds every facet refinement shares: round 0 looks at every interface facet, later rounds
/// only at the facets of cells created by the previous round's insertions (the cells incident to
/// the new vertices; the rest did not change). `candidateOf(facet)` gives the facet's point (in
/// parallel; deviation 0 = none); the points go in through insertCandidates and the cells around
/// them are relabelled, until a round finds or inserts nothing (at most kRefineRounds). `name`
/// heads the debug lines. Returns the number of points inserted.
template <class CandidateOf>
size_t refineInterfaceFacets(const IndicatorField& field, Delaunay& dt, const char* name,
                             RunContext& ctx, const CandidateOf& candidateOf) {
  const PreprocessedVolume& vol = field.volume();
  const double smin = std::min({vol.spacing[0], vol.spacing[1], vol.spacing[2]});
  const int threads = resolveThreads(ctx.threads());
  size_t inserted = 0;
  std::vector<Delaunay::Vertex_handle> fresh;
  auto addFacet = [](std::vector<InterfaceFacet>& out, Delaunay::Cell_handle c, int i) {
    const auto n = c->neighbor(i);
    if (c->info() == n->info()) return;
    InterfaceFacet x;
    x.a = std::min(c->info(), n->info());
    x.b = std::max(c->info(), n->info());
    x.cell = c;
    x.index = i;
    for (int k = 0; k < 3; ++k) {
      const Point& q = c->vertex((i + 1 + k) % 4)->point();
      x.p[size_t(k)] = {q.x(), q.y(), q.z()};
    }
    std::sort(x.p.begin(), x.p.end());
    out.push_back(x);
  };
  for (int round = 0; round < kRefineRounds; ++round) {
    const auto t0 = std::chrono::steady_clock::now();
    std::vector<InterfaceFacet> facets;
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
    parallelFor(
        facets.size(), threads,
        [&](size_t lo, size_t hi, int) {
          for (size_t i = lo; i < hi; ++i) {
            if ((i & 0xFFFF) == 0 && ctx.isCanceled()) return;
            cand[i] = candidateOf(facets[i]);
          }
        },
        64);  // most facets return at once, a few march and bisect: many chunks balance them
    ctx.checkCancel();
    const size_t found = size_t(std::count_if(cand.begin(), cand.end(),
                                              [](const Candidate& c) { return c.deviation != 0; }));
    if (found == 0) break;
    fresh = insertCandidates(field, dt, std::move(cand), smin, threads);
    const size_t roundInserted = fresh.size();
    inserted += roundInserted;
    ctx.debug(std::string(name) + " refinement round " + std::to_string(round) + ": " +
              std::to_string(facets.size()) + " facets checked, " + std::to_string(found) +
              " to refine, " + std::to_string(roundInserted) + " points inserted (" +
              std::to_string(secondsSince(t0)) + " s)");
    if (roundInserted == 0) break;
    relabelAround(field, dt, fresh, threads);
  }
  return inserted;
}

/// Clips the segment [from, to] (canonical mm) to the grid's box (Liang-Barsky in voxel
/// coordinates); false when it misses the box.
bool clipToGrid(const PreprocessedVolume& vol, Vec3& from, Vec3& to) {
  const Vec3 p = vol.canonicalToLocal(from), q = vol.canonicalToLocal(to);
  double t0 = 0, t1 = 1;
  for (int k = 0; k < 3; ++k) {
    const double d = q[k] - p[k], hi = vol.dims[k] - 1;
    if (d == 0) {
      if (p[k] < 0 || p[k] > hi) return false;
      continue;
    }
    double ta = (0 - p[k]) / d, tb = (hi - p[k]) / d;
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
  }
  if (t0 > t1) return false;
  const Vec3 a = from, b = to;
  for (int k = 0; k < 3; ++k) {
    from[k] = a[k] + t0 * (b[k] - a[k]);
    to[k] = a[k] + t1 * (b[k] - a[k]);
  }
  return true;
}

/// The first crossing of the interface between labels a and b (f_a = f_b) on the segment from
/// `from` to `to` (canonical mm), marched in steps of at most `step` then bisected; false when
/// f_a - f_b keeps its sign.
bool crossingOnSegment(const IndicatorField& field, int a, int b, const Vec3& from, const Vec3& to,
                       double step, Vec3& out) {
  const PreprocessedVolume& vol = field.volume();
  auto at = [&](double t) {
    return Vec3{from[0] + t * (to[0] - from[0]), from[1] + t * (to[1] - from[1]),
                from[2] + t * (to[2] - from[2])};
  };
  auto phi = [&](double t) {
    const Vec3 l = vol.canonicalToLocal(at(t));
    return field.eval(a, l) - field.eval(b, l);
  };
  const double len = std::sqrt(dist2(from, to));
  const int steps = std::max(1, std::min(512, int(std::ceil(len / step))));
  const bool s0 = phi(0) <= 0;
  double tIn = 0, tOut = -1;
  for (int k = 1; k <= steps; ++k) {
    const double t = double(k) / steps;
    if ((phi(t) <= 0) != s0) {
      tIn = double(k - 1) / steps;
      tOut = t;
      break;
    }
  }
  if (tOut < 0) return false;
  for (int it = 0; it < 40; ++it) {
    const double mid = 0.5 * (tIn + tOut);
    if ((phi(mid) <= 0) == s0)
      tIn = mid;
    else
      tOut = mid;
  }
  out = at(0.5 * (tIn + tOut));
  return true;
}

}  // namespace

size_t refineFacetDistance(const IndicatorField& field, LabelledDelaunay& delaunay, double delta,
                           RunContext& ctx) {
  const PreprocessedVolume& vol = field.volume();
  const double smin = std::min({vol.spacing[0], vol.spacing[1], vol.spacing[2]});
  const Candidate none{0, {0, 0, 0}, 0};
  return refineInterfaceFacets(
      field, delaunay.impl->dt, "Facet-distance", ctx, [&](const InterfaceFacet& F) -> Candidate {
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
        if (!(nl > 0) || minEdge < 2 * delta) return none;
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
            if ((phi(mid) <= 0) == (vIn <= 0))
              tIn = mid;
            else
              tOut = mid;
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
        if (bestDeviation == 0) return none;
        return Candidate{bestDeviation, best, 0.5 * minEdge};
      });
}

size_t refineFacetShape(const IndicatorField& field, LabelledDelaunay& delaunay,
                        const std::function<double(const Vec3&)>& sizeAt,
                        const FacetShapeCriteria& criteria, RunContext& ctx) {
  const Delaunay& dt = delaunay.impl->dt;
  const PreprocessedVolume& vol = field.volume();
  const double smin = std::min({vol.spacing[0], vol.spacing[1], vol.spacing[2]});
  const double sinBound = std::sin(criteria.minAngleDegrees * M_PI / 180.0);
  const double tol = 0.002;  // voxels: inside the grid, as snapToBox puts points on its box
  const Candidate none{0, {0, 0, 0}, 0};
  auto circumcentre = [](Delaunay::Cell_handle c) {
    const Point q = CGAL::circumcenter(c->vertex(0)->point(), c->vertex(1)->point(),
                                       c->vertex(2)->point(), c->vertex(3)->point());
    return Vec3{q.x(), q.y(), q.z()};
  };
  return refineInterfaceFacets(
      field, delaunay.impl->dt, "Facet-shape", ctx, [&](const InterfaceFacet& F) -> Candidate {
        std::array<double, 3> len;
        for (int k = 0; k < 3; ++k)
          len[size_t(k)] = std::sqrt(dist2(F.p[size_t(k)], F.p[size_t((k + 1) % 3)]));
        std::sort(len.begin(), len.end());
        const Vec3 u = sub(F.p[1], F.p[0]), v = sub(F.p[2], F.p[0]);
        Vec3 nrm = cross(u, v);
        const double twiceArea = norm(nrm);
        // The smallest angle lies between the two longest edges.
        if (!(twiceArea > 0) || twiceArea >= sinBound * len[1] * len[2]) return none;
        Vec3 g;
        for (int a = 0; a < 3; ++a) g[a] = (F.p[0][a] + F.p[1][a] + F.p[2][a]) / 3.0;
        const double h = sizeAt(g);
        if (!(len[2] > criteria.sizeFactor * h)) return none;
        for (auto& x : nrm) x /= twiceArea;
        auto inGrid = [&](const Vec3& x) {
          const Vec3 l = vol.canonicalToLocal(x);
          for (int k = 0; k < 3; ++k)
            if (l[k] < -tol || l[k] > vol.dims[k] - 1 + tol) return false;
          return true;
        };
        // Near the volume's box (within a voxel, not on it) a point would make flat tets against
        // the box's own points: the box faces are left to the other refinements.
        auto usable = [&](const Vec3& q) {
          if (!inGrid(q)) return false;
          const Vec3 l = vol.canonicalToLocal(q);
          if (field.snapToBox(l, smin) != l) return false;
          const int am = field.argmax(l);
          return am == F.a || am == F.b;
        };
        // The surface Delaunay ball's centre: where the dual Voronoi edge crosses the interface.
        // The edge runs from circumcentre to circumcentre, or, next to the infinite cell, from the
        // finite cell's circumcentre outwards along the normal; it is clipped to the grid. The ball
        // is empty, so every vertex is at least its radius from the centre.
        Delaunay::Cell_handle c = F.cell, n = c->neighbor(F.index);
        if (dt.is_infinite(c)) std::swap(c, n);
        Vec3 from = circumcentre(c), to;
        if (!dt.is_infinite(n)) {
          to = circumcentre(n);
        } else {
          const Point& o = c->vertex(c->index(n))->point();
          Vec3 out = nrm;
          if (dot(out, sub(Vec3{o.x(), o.y(), o.z()}, F.p[0])) > 0)
            for (auto& x : out) x = -x;
          const double reach = std::fabs(dot(out, sub(from, F.p[0]))) + 2 * len[2];
          to = {from[0] + reach * out[0], from[1] + reach * out[1], from[2] + reach * out[2]};
        }
        Vec3 q;
        if (clipToGrid(vol, from, to) &&
            crossingOnSegment(field, F.a, F.b, from, to, 0.25 * smin, q) && usable(q)) {
          const double r = std::sqrt(dist2(q, F.p[0]));
          if (r <= 2 * len[2]) return Candidate{len[2] / h, q, 0.5 * r};
        }
        // Else (a flat cell's circumcentre far away, or the hull's outside): the longest edge's
        // midpoint, moved along the triangle's normal onto the interface.
        int longest = 0;
        for (int k = 1; k < 3; ++k)
          if (dist2(F.p[size_t(k)], F.p[size_t((k + 1) % 3)]) >
              dist2(F.p[size_t(longest)], F.p[size_t((longest + 1) % 3)]))
            longest = k;
        const Vec3 &e0 = F.p[size_t(longest)], &e1 = F.p[size_t((longest + 1) % 3)];
        const Vec3 mid{0.5 * (e0[0] + e1[0]), 0.5 * (e0[1] + e1[1]), 0.5 * (e0[2] + e1[2])};
        const double reach = 0.75 * len[2];
        Vec3 best;
        double bestDistance = 1e300;
        for (double sgn : {1.0, -1.0}) {
          const Vec3 to{mid[0] + sgn * reach * nrm[0], mid[1] + sgn * reach * nrm[1],
                        mid[2] + sgn * reach * nrm[2]};
          if (!crossingOnSegment(field, F.a, F.b, mid, to, 0.25 * smin, q) || !usable(q)) continue;
          const double d = dist2(q, mid);
          if (d < bestDistance) {
            bestDistance = d;
            best = q;
          }
        }
        if (bestDistance == 1e300) return none;
        return Candidate{len[2] / h, best, std::min(0.25 * len[2], 0.4 * h)};
      });
}

size_t refineVoxelCentres(const IndicatorField& field, LabelledDelaunay& delaunay,
                          RunContext& ctx) {
  Delaunay& dt = delaunay.impl->dt;
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
          static const int o[6][3] = {{1, 0, 0},  {-1, 0, 0}, {0, 1, 0},
                                      {0, -1, 0}, {0, 0, 1},  {0, 0, -1}};
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
    parallelFor(
        voxels.size(), threads,
        [&](size_t lo, size_t hi, int) {
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
              Vec3 ga, gb;  // f's value and gradient from one lookup of the cell
              const double F = field.evalGradient(a, l, ga) - field.evalGradient(b, l, gb);
              if (std::fabs(F) < 1e-4 * smin) {
                ok = true;
                break;
              }
              const Vec3 g{(ga[0] - gb[0]) / vol.spacing[0], (ga[1] - gb[1]) / vol.spacing[1],
                           (ga[2] - gb[2]) / vol.spacing[2]};
              const double g2 = g[0] * g[0] + g[1] * g[1] + g[2] * g[2];
              if (g2 < 1e-20) break;
              Vec3 step{-F * g[0] / g2, -F * g[1] / g2, -F * g[2] / g2};
              const double len =
                  std::sqrt(step[0] * step[0] + step[1] * step[1] + step[2] * step[2]);
              if (len > 0.5 * smin)
                for (auto& x : step) x *= 0.5 * smin / len;
              const Vec3 cc = vol.localToCanonical(l);
              l = vol.canonicalToLocal({cc[0] + step[0], cc[1] + step[1], cc[2] + step[2]});
            }
            if (!ok) continue;
            const int am = field.argmax(l);
            if (am != a && am != b) continue;
            const Vec3 q = vol.localToCanonical(l);
            const double dist =
                std::sqrt((q[0] - c[0]) * (q[0] - c[0]) + (q[1] - c[1]) * (q[1] - c[1]) +
                          (q[2] - c[2]) * (q[2] - c[2]));
            if (dist > 2 * smin) continue;                   // not the interface next to this voxel
            cand[n] = {1.0 / (1.0 + dist), q, 0.25 * smin};  // nearest surface points first
          }
        },
        chunks);
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

JunctionRefinement refineJunctionEdges(const IndicatorField& field, LabelledDelaunay& delaunay,
                                       const Junctions& junctions, RunContext& ctx) {
  return JunctionRefiner(field, delaunay.impl->dt, junctions, ctx).run();
}

}  // namespace femesher
