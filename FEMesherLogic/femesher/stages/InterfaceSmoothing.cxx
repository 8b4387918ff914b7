// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/VecMath.h>
#include <femesher/stages/InterfaceSmoothing.h>
#include <femesher/stages/Junctions.h>
#include <femesher/stages/internal/OptimizeEditor.h>

#include <algorithm>
#include <cmath>

namespace femesher {

namespace {

using optimize_detail::Editor;
using optimize_detail::MoveConstraint;

/// Moves `x` (local index) onto f_a = f_b by Newton steps along the gradient of f_a - f_b
/// (canonical metric); see InterfaceSmoothing.h.
bool toInterface(const IndicatorField& f, int a, int b, Vec3& x) {
  const PreprocessedVolume& vol = f.volume();
  const double h = vol.minSpacing(), tol = 1e-4 * h;
  const Vec3 start = vol.localToCanonical(x);
  for (int it = 0; it < 25; ++it) {
    const double gap = f.eval(a, x) - f.eval(b, x);
    const Vec3 ga = f.gradient(a, x), gb = f.gradient(b, x);
    Vec3 d;
    for (int k = 0; k < 3; ++k) d[k] = (ga[k] - gb[k]) / vol.spacing[k];
    if (std::fabs(gap) < tol) {
      if (norm(sub(vol.localToCanonical(x), start)) > 2 * h) return false;
      int around[8];
      const int n = f.cornerLabels(x, around);
      const double own = std::min(f.eval(a, x), f.eval(b, x));
      for (int c = 0; c < n; ++c)
        if (around[c] != a && around[c] != b && f.eval(around[c], x) > own + 10 * tol) return false;
      return true;
    }
    const double dd = dot(d, d);
    if (!(dd > 1e-20)) return false;
    double s = -gap / dd;
    const double len = std::fabs(s) * std::sqrt(dd);
    if (len > 0.5 * h) s *= 0.5 * h / len;
    for (int k = 0; k < 3; ++k) x[k] += s * d[k] / vol.spacing[k];
  }
  return false;
}

/// Share of the facet distance an interface triangle may always reach (see smoothInterfaceVertex).
constexpr double kFacetShare = 0.25;

/// A face of a vertex's star on an interface: its vertices and the materials a < b either side.
struct InterfaceFace {
  std::array<int32_t, 3> v;
  int a, b;
  Vec3 normal;  ///< area-weighted, from a towards b
};

bool onBox(const OptimizeInterfaces& in, const Vec3& p) {
  if (!in.hasBox) return false;
  for (int k = 0; k < 3; ++k)
    if (std::fabs(p[k] - in.boxLo[k]) <= in.boxTolerance ||
        std::fabs(p[k] - in.boxHi[k]) <= in.boxTolerance)
      return true;
  return false;
}

/// The materials around v (sorted, background 0 for outer faces) and its interface faces.
void vertexInterfaces(const Editor& m, int32_t v, std::vector<int>& materials,
                      std::vector<InterfaceFace>& faces) {
  materials.clear();
  faces.clear();
  for (uint32_t t : m.around[size_t(v)]) {
    materials.push_back(m.labels[t]);
    for (int k = 0; k < 4; ++k) {
      const int32_t opposite = m.tets[t][size_t(k)];
      if (opposite == v) continue;
      const auto f = m.face(t, k);
      const int64_t s = m.across(t, f[0], f[1], f[2]);
      const int own = m.labels[t], other = s < 0 ? 0 : m.labels[size_t(s)];
      if (other == own || (s >= 0 && other < own)) continue;  // inside, or seen from the other side
      if (s < 0) materials.push_back(0);
      const Vec3& A = m.pts[size_t(f[0])];
      Vec3 n = cross(sub(m.pts[size_t(f[1])], A), sub(m.pts[size_t(f[2])], A));
      if (dot(n, sub(m.pts[size_t(opposite)], A)) > 0) n = {-n[0], -n[1], -n[2]};  // out of t
      if (other < own) n = {-n[0], -n[1], -n[2]};  // from the smaller label
      faces.push_back({f, std::min(own, other), std::max(own, other), n});
    }
  }
  std::sort(materials.begin(), materials.end());
  materials.erase(std::unique(materials.begin(), materials.end()), materials.end());
}

/// Distance (mm) from the centroid of `f` to its interface; -1 when the projection fails.
double centroidDistance(const Editor& m, const OptimizeInterfaces& in, const InterfaceFace& f) {
  Vec3 g{0, 0, 0};
  for (int32_t w : f.v)
    for (int k = 0; k < 3; ++k) g[k] += m.pts[size_t(w)][k] / 3;
  Vec3 q = g;
  return in.projectOntoInterface(f.a, f.b, q) ? norm(sub(q, g)) : -1.0;
}

/// The unit direction of the triple line through a vertex: across the normals of its two most
/// different interface pairs; zero when they are (nearly) parallel.
Vec3 tripleLineDirection(const std::vector<InterfaceFace>& faces) {
  std::vector<std::pair<std::pair<int, int>, Vec3>> pairs;
  for (const auto& f : faces) {
    auto it = std::find_if(pairs.begin(), pairs.end(),
                           [&](const auto& p) { return p.first == std::make_pair(f.a, f.b); });
    if (it == pairs.end()) {
      pairs.push_back({{f.a, f.b}, f.normal});
    } else {
      for (int k = 0; k < 3; ++k) it->second[k] += f.normal[k];
    }
  }
  Vec3 best{0, 0, 0};
  double bestSin = 0.2;  // below ~11.5 degrees between the sheets: no reliable direction
  for (size_t i = 0; i < pairs.size(); ++i)
    for (size_t j = i + 1; j < pairs.size(); ++j) {
      const Vec3 c = cross(pairs[i].second, pairs[j].second);
      const double s = norm(c) / (norm(pairs[i].second) * norm(pairs[j].second));
      if (s > bestSin) {
        bestSin = s;
        best = {c[0] / norm(c), c[1] / norm(c), c[2] / norm(c)};
      }
    }
  return best;
}

}  // namespace

namespace optimize_detail {

bool smoothInterfaceVertex(Editor& m, int32_t v, const OptimizeInterfaces& in, int& kind) {
  kind = 0;
  if (onBox(in, m.pts[size_t(v)])) return false;
  std::vector<int> materials;
  std::vector<InterfaceFace> faces;
  vertexInterfaces(m, v, materials, faces);
  if (materials.size() != 2 && materials.size() != 3) return false;
  kind = int(materials.size());
  MoveConstraint c;
  if (kind == 2) {
    Vec3 n{0, 0, 0};
    for (const auto& f : faces)
      for (int k = 0; k < 3; ++k) n[k] += f.normal[k];
    const double len = norm(n);
    if (!(len > 0)) return false;
    n = {n[0] / len, n[1] / len, n[2] / len};
    c.tangent = [n](const Vec3& d) {
      const double x = dot(d, n);
      return Vec3{d[0] - x * n[0], d[1] - x * n[1], d[2] - x * n[2]};
    };
    const int a = materials[0], b = materials[1];
    c.project = [&in, a, b](Vec3& p) { return in.projectOntoInterface(a, b, p); };
  } else {
    if (!in.projectOntoJunction) return false;
    const Vec3 t = tripleLineDirection(faces);
    if (!(norm(t) > 0)) return false;
    c.tangent = [t](const Vec3& d) {
      const double x = dot(d, t);
      return Vec3{x * t[0], x * t[1], x * t[2]};
    };
    const std::array<int, 3> abc{{materials[0], materials[1], materials[2]}};
    c.project = [&in, abc](Vec3& p) { return in.projectOntoJunction(abc, p); };
  }
  // Each interface triangle may end at most max(its distance now, a quarter of the facet
  // distance) from its interface, and never beyond the facet distance unless it is already.
  std::vector<double> bound(faces.size());
  for (size_t i = 0; i < faces.size(); ++i) {
    bound[i] = centroidDistance(m, in, faces[i]);
    if (bound[i] < 0) return false;
    bound[i] = std::max(bound[i], kFacetShare * in.facetDistance);
  }
  // The net volume the moves add to or take from a material stays within its budget.
  std::vector<std::pair<int, double>> starVolume;
  for (uint32_t t : m.around[size_t(v)]) starVolume.push_back({m.labels[t], -m.volume(t)});
  auto volumeChange = [&](std::vector<double>& change) {
    change.assign(m.startVolume.size(), 0);
    size_t i = 0;
    for (uint32_t t : m.around[size_t(v)]) change[size_t(m.labels[t])] += starVolume[i++].second + m.volume(t);
  };
  std::vector<double> change;
  c.accept = [&]() {
    for (size_t i = 0; i < faces.size(); ++i) {
      const double d = centroidDistance(m, in, faces[i]);
      if (d < 0 || d > bound[i]) return false;
    }
    volumeChange(change);
    for (size_t l = 0; l < change.size(); ++l)
      if (std::fabs(m.movedVolume[l] + change[l]) > kVolumeBudget * m.startVolume[l]) return false;
    return !onBox(in, m.pts[size_t(v)]);
  };
  if (!smoothVertex(m, v, &c)) return false;
  volumeChange(change);
  for (size_t l = 0; l < change.size(); ++l) m.movedVolume[l] += change[l];
  return true;
}

bool flipInterfaceEdge(Editor& m, uint32_t t, const OptimizeInterfaces& in,
                       std::vector<uint32_t>& fresh) {
  const auto T = m.tets[t];
  const int own = m.labels[t];
  int64_t nb[4];
  for (int k = 0; k < 4; ++k) {
    const auto f = m.face(t, k);
    nb[k] = m.across(t, f[0], f[1], f[2]);
    if (nb[k] < 0) return false;  // outer boundary: peeling's business
  }
  std::vector<uint32_t> ring;
  for (int i = 0; i < 4; ++i)
    for (int j = i + 1; j < 4; ++j) {
      // Faces opposite c = T[i] and d = T[j] share the edge (a, b); both on the interface with
      // one other material, the other two faces inside t's material.
      const int other = m.labels[size_t(nb[i])];
      if (other == own || m.labels[size_t(nb[j])] != other) continue;
      int32_t ab[2], n = 0;
      bool inside = true;
      for (int k = 0; k < 4; ++k)
        if (k != i && k != j) {
          ab[n++] = T[size_t(k)];
          inside &= m.labels[size_t(nb[k])] == own;
        }
      if (!inside) continue;
      m.tetsOnEdge(ab[0], ab[1], ring);
      if (std::any_of(ring.begin(), ring.end(),
                      [&](uint32_t s) { return s != t && m.labels[s] != other; }))
        continue;
      // The new interface triangles (b, c, d) and (a, c, d): within the facet distance bound.
      const int lo = std::min(own, other), hi = std::max(own, other);
      bool near = true;
      for (int k = 0; k < 2 && near; ++k) {
        const InterfaceFace f{{ab[1 - k], T[size_t(i)], T[size_t(j)]}, lo, hi, {0, 0, 0}};
        const double d = centroidDistance(m, in, f);
        near = d >= 0 && d <= kFacetShare * in.facetDistance;
      }
      const double v = m.volume(t);
      if (!near || std::fabs(m.movedVolume[size_t(own)] - v) > kVolumeBudget * m.startVolume[size_t(own)] ||
          std::fabs(m.movedVolume[size_t(other)] + v) > kVolumeBudget * m.startVolume[size_t(other)])
        continue;
      // t joins the other material: (a, b) is then inside it, and removing that edge must help.
      m.relabel(t, other);
      if (removeEdge(m, t, ab[0], ab[1], fresh)) {
        m.movedVolume[size_t(own)] -= v;
        m.movedVolume[size_t(other)] += v;
        return true;
      }
      m.relabel(t, own);
    }
  return false;
}

bool relabelFlatTet(Editor& m, uint32_t t, const OptimizeInterfaces& in, double tolerance,
                    std::vector<uint32_t>& fresh) {
  const int own = m.labels[t];
  if (tolerance <= 0 || m.perLabel[size_t(own)] <= 1 || !(m.thickness(t) <= tolerance))
    return false;
  int64_t nb[4];
  int ownFaces = 0;
  for (int k = 0; k < 4; ++k) {
    const auto f = m.face(t, k);
    nb[k] = m.across(t, f[0], f[1], f[2]);
    if (nb[k] < 0) return false;  // outer boundary: peeling's business
    ownFaces += m.labels[size_t(nb[k])] == own;
  }
  // Candidates: the other materials on t's faces, most faces first (ties: smaller label).
  std::vector<std::pair<int, int>> candidates;  // (-faces, label)
  for (int k = 0; k < 4; ++k) {
    const int l = m.labels[size_t(nb[k])];
    if (l == own) continue;
    int n = 0;
    for (int j = 0; j < 4; ++j) n += m.labels[size_t(nb[j])] == l;
    if (std::find(candidates.begin(), candidates.end(), std::make_pair(-n, l)) == candidates.end())
      candidates.push_back({-n, l});
  }
  std::sort(candidates.begin(), candidates.end());
  const double v = m.volume(t);
  for (const auto& [negFaces, other] : candidates) {
    // More faces on `other` than on its own material: the relabelling lowers the number of
    // constrained faces (so it cannot be undone and redone). As many or fewer: only when an edge
    // of t can then be removed, or a face flipped, inside `other` (an interface flip of a more
    // general kind, which raises the worst angle, so it cannot be undone either).
    // Every face that becomes an interface stays within the facet distance of its smooth
    // interface. Where that cannot be checked (the projection fails: near a junction of more
    // materials, the pair is not the leading one), a tet thinner than a tenth of the facet
    // distance may still go: its faces lie that close to the interface faces they replace.
    const bool sliver = m.thickness(t) <= 0.1 * in.facetDistance;
    bool near = true;
    for (int k = 0; k < 4 && near; ++k) {
      const int l = m.labels[size_t(nb[k])];
      if (l == other) continue;
      const InterfaceFace f{m.face(t, k), std::min(l, other), std::max(l, other), {0, 0, 0}};
      const double d = centroidDistance(m, in, f);
      near = d >= 0 ? d <= in.facetDistance : sliver;
    }
    if (!near ||
        std::fabs(m.movedVolume[size_t(own)] - v) > kVolumeBudget * m.startVolume[size_t(own)] ||
        std::fabs(m.movedVolume[size_t(other)] + v) > kVolumeBudget * m.startVolume[size_t(other)])
      continue;
    m.relabel(t, other);
    bool done = -negFaces > ownFaces;
    if (done) {
      fresh.push_back(t);
    } else {
      const auto T = m.tets[t];
      for (int i = 0; i < 4 && !done; ++i)
        for (int j = i + 1; j < 4 && !done; ++j)
          done = removeEdge(m, t, T[size_t(i)], T[size_t(j)], fresh);
      for (int k = 0; k < 4 && !done; ++k) done = flipFace(m, t, k, fresh);
    }
    if (!done) {
      m.relabel(t, own);
      continue;
    }
    m.movedVolume[size_t(own)] -= v;
    m.movedVolume[size_t(other)] += v;
    return true;
  }
  return false;
}

}  // namespace optimize_detail

OptimizeInterfaces indicatorInterfaces(const IndicatorField& field, double facetDistanceVoxels) {
  const PreprocessedVolume& vol = field.volume();
  OptimizeInterfaces in;
  in.facetDistance = facetDistanceVoxels * vol.minSpacing();
  in.projectOntoInterface = [&field](int a, int b, Vec3& p) {
    const PreprocessedVolume& grid = field.volume();
    Vec3 x = grid.canonicalToLocal(p);
    if (!toInterface(field, a, b, x)) return false;
    p = grid.localToCanonical(x);
    return true;
  };
  in.projectOntoJunction = [&field](const std::array<int, 3>& abc, Vec3& p) {
    const PreprocessedVolume& grid = field.volume();
    const uint16_t labels[3] = {uint16_t(abc[0]), uint16_t(abc[1]), uint16_t(abc[2])};
    Vec3 x = grid.canonicalToLocal(p);
    if (!locateJunctionPoint(field, labels, 3, x)) return false;
    if (norm(sub(grid.localToCanonical(x), p)) > 2 * grid.minSpacing()) return false;
    p = grid.localToCanonical(x);
    return true;
  };
  if (vol.inputDims[0] > 0) {
    in.hasBox = true;
    for (int k = 0; k < 3; ++k) {
      in.boxLo[k] = -0.5 * vol.spacing[k];
      in.boxHi[k] = (vol.inputDims[k] - 0.5) * vol.spacing[k];
    }
    in.boxTolerance = 0.01 * vol.minSpacing();
  }
  return in;
}

}  // namespace femesher
