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


/// A projection that leaves a point anywhere within `offset` of where `onto` would put it: farther
/// points are pulled back to 0.95 × offset along the projection, which (a Newton descent, not the
/// exact nearest point) is then checked again from where the point ends.
std::function<bool(Vec3&)> withinOffset(std::function<bool(Vec3&)> onto, double offset) {
  return [onto = std::move(onto), offset](Vec3& p) {
    Vec3 q = p;
    if (!onto(q)) return false;
    const Vec3 d = sub(p, q);
    const double len = norm(d);
    if (len > 0.95 * offset)
      for (int k = 0; k < 3; ++k) p[k] = q[k] + d[k] * 0.95 * offset / len;
    q = p;
    return onto(q) && norm(sub(p, q)) <= offset;
  };
}

/// Share of the facet distance an interface triangle may always reach (see smoothInterfaceVertex).
constexpr double kFacetShare = 0.25;

/// A face of a vertex's star on an interface: its vertices and the materials a < b either side.
struct InterfaceFace {
  std::array<int32_t, 3> v;
  int a, b;
  Vec3 normal;  ///< area-weighted, from a towards b
};

/// The materials around v (sorted, background 0 for outer faces not on the volume's box) and its
/// interface faces.
void vertexInterfaces(const Editor& m, const OptimizeInterfaces& in, int32_t v,
                      std::vector<int>& materials, std::vector<InterfaceFace>& faces) {
  materials.clear();
  faces.clear();
  // Every face here holds v, so the tet across it is in v's star: pair the star's faces by their
  // two other vertices (a face held by more than two tets is left to Editor::across, which picks
  // the same tet it always did).
  const auto& star = m.around[size_t(v)];
  thread_local std::vector<std::pair<std::array<int32_t, 2>, uint32_t>> keys;
  thread_local std::vector<int64_t> acrossOf;
  keys.clear();
  acrossOf.assign(4 * star.size(), -1);
  for (size_t i = 0; i < star.size(); ++i)
    for (int k = 0; k < 4; ++k) {
      const auto& T = m.tets[star[i]];
      if (T[size_t(k)] == v) continue;
      std::array<int32_t, 2> o{};
      int n = 0;
      for (int c = 0; c < 4; ++c)
        if (c != k && T[size_t(c)] != v) o[size_t(n++)] = T[size_t(c)];
      if (o[0] > o[1]) std::swap(o[0], o[1]);
      keys.push_back({o, uint32_t(4 * i + size_t(k))});
    }
  std::sort(keys.begin(), keys.end());
  for (size_t a = 0; a < keys.size();) {
    size_t b = a + 1;
    while (b < keys.size() && keys[b].first == keys[a].first) ++b;
    if (b - a == 2) {
      acrossOf[keys[a].second] = int64_t(star[keys[a + 1].second / 4]);
      acrossOf[keys[a + 1].second] = int64_t(star[keys[a].second / 4]);
    } else if (b - a > 2) {
      for (size_t c = a; c < b; ++c) acrossOf[keys[c].second] = -2;
    }
    a = b;
  }
  for (size_t i = 0; i < star.size(); ++i) {
    const uint32_t t = star[i];
    materials.push_back(m.labels[t]);
    for (int k = 0; k < 4; ++k) {
      const int32_t opposite = m.tets[t][size_t(k)];
      if (opposite == v) continue;
      const auto f = m.face(t, k);
      int64_t s = acrossOf[4 * i + size_t(k)];
      if (s == -2) s = m.across(t, f[0], f[1], f[2]);
      const int own = m.labels[t], other = s < 0 ? 0 : m.labels[size_t(s)];
      if (other == own || (s >= 0 && other < own)) continue;  // inside, or seen from the other side
      if (s < 0 && (in.boxPlanes(m.pts[size_t(f[0])]) &
                    in.boxPlanes(m.pts[size_t(f[1])]) &
                    in.boxPlanes(m.pts[size_t(f[2])])) != 0)
        continue;  // on the volume's box: not an interface
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
  return optimize_detail::faceDistance(m, in, f.v, f.a, f.b);
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

double faceDistance(const Editor& m, const OptimizeInterfaces& in, const std::array<int32_t, 3>& f,
                    int a, int b) {
  Vec3 g{0, 0, 0};
  for (int32_t w : f)
    for (int k = 0; k < 3; ++k) g[k] += m.pts[size_t(w)][k] / 3;
  Vec3 q = g;
  return in.projectOntoInterface(a, b, q) ? norm(sub(q, g)) : -1.0;
}

bool smoothInterfaceVertex(Editor& m, int32_t v, const OptimizeInterfaces& in, int& kind,
                           double offset) {
  kind = 0;
  // On the volume's box: only on one of its planes, between two materials; it then moves along
  // the line where their interface meets that plane.
  const int box = in.boxPlanes(m.pts[size_t(v)]);
  if (box != 0 && (box & (box - 1)) != 0) return false;  // a box edge or corner
  std::vector<int> materials;
  std::vector<InterfaceFace> faces;
  vertexInterfaces(m, in, v, materials, faces);
  if (materials.size() < 2 || (box != 0 && materials.size() != 2)) return false;
  kind = std::min(int(materials.size()), 4);
  const Vec3 lineDirection = kind == 3 ? tripleLineDirection(faces) : Vec3{0, 0, 0};
  // Off the line (offset > 0) the move needs no direction: three nearly parallel sheets (a thin
  // wedge of one material ending between two others) have none, and are where it helps most.
  if (kind == 3 && (!in.projectOntoJunction || (offset <= 0 && !(norm(lineDirection) > 0))))
    return false;
  MoveConstraint c;
  const Vec3 start = m.pts[size_t(v)];
  if (kind == 4) {
    // A junction of four or more materials: it may move anywhere within a quarter of the facet
    // distance of where it was before the first move.
    const Vec3 anchor = m.junctionStart.emplace(v, start).first->second;
    const double radius = offset > 0 ? offset : kFacetShare * in.facetDistance;
    c.project = [anchor, radius](Vec3& p) {
      const Vec3 d = sub(p, anchor);
      const double len = norm(d);
      if (len > radius)
        for (int k = 0; k < 3; ++k) p[k] = anchor[k] + d[k] * radius / len;
      return true;
    };
  } else if (kind == 2) {
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
    if (box != 0) {
      int axis = 0;
      while (!(box & (3 << (2 * axis)))) ++axis;
      const double plane = (box & (1 << (2 * axis))) ? in.boxLo[size_t(axis)] : in.boxHi[size_t(axis)];
      Vec3 e{0, 0, 0};
      e[size_t(axis)] = 1;
      Vec3 line = cross(n, e);  // the interface's trace on the plane
      const double sine = norm(line);
      if (!(sine > 0.2)) return false;  // the interface nearly parallel to the box plane
      line = {line[0] / sine, line[1] / sine, line[2] / sine};
      c.tangent = [line](const Vec3& d) {
        const double x = dot(d, line);
        return Vec3{x * line[0], x * line[1], x * line[2]};
      };
      // Alternating projections onto the interface and the plane (they cross at more than
      // about 11 degrees, see above): converged when the interface step is negligible.
      const double tol = 1e-4 * in.facetDistance;
      c.project = [&in, a, b, axis, plane, tol](Vec3& p) {
        for (int it = 0; it < 20; ++it) {
          p[size_t(axis)] = plane;
          Vec3 q = p;
          if (!in.projectOntoInterface(a, b, q)) return false;
          const double step = norm(sub(q, p));
          p = q;
          if (step < tol) {
            p[size_t(axis)] = plane;
            return true;
          }
        }
        return false;
      };
    }
  } else {
    const Vec3 t = lineDirection;
    c.tangent = [t](const Vec3& d) {
      const double x = dot(d, t);
      return Vec3{x * t[0], x * t[1], x * t[2]};
    };
    const std::array<int, 3> abc{{materials[0], materials[1], materials[2]}};
    c.project = [&in, abc](Vec3& p) { return in.projectOntoJunction(abc, p); };
  }
  if (offset > 0 && kind != 4) {  // anywhere within `offset` of the interface, trace or line
    c.project = withinOffset(std::move(c.project), offset);
    if (box == 0) {
      c.tangent = nullptr;
    } else {  // in the box's plane
      int axis = 0;
      while (!(box & (3 << (2 * axis)))) ++axis;
      c.tangent = [axis](const Vec3& d) {
        Vec3 x = d;
        x[size_t(axis)] = 0;
        return x;
      };
    }
  }
  // Each interface triangle may end at most max(its distance now, a quarter of the facet
  // distance) from its interface (0.95 × the facet distance for an off-interface move), and
  // never beyond the facet distance unless it is already.
  // Around a junction point, a triangle whose interface cannot be found (another material leads
  // at its centroid) is bounded by the quarter facet distance the point may move (bound -1).
  // On a triple line, a triangle whose own interface cannot be found (in a thin wedge the third
  // material leads at its centroid) is measured to the triple line instead, a point of its
  // interface: never nearer than the interface itself, so the bound is conservative.
  auto distance = [&](const InterfaceFace& f) {
    const double d = centroidDistance(m, in, f);
    if (d >= 0 || kind != 3) return d;
    Vec3 g{0, 0, 0};
    for (int32_t w : f.v)
      for (int k = 0; k < 3; ++k) g[k] += m.pts[size_t(w)][k] / 3;
    Vec3 q = g;
    const std::array<int, 3> abc{{materials[0], materials[1], materials[2]}};
    return in.projectOntoJunction(abc, q) ? norm(sub(q, g)) : -1.0;
  };
  std::vector<double> bound(faces.size());
  for (size_t i = 0; i < faces.size(); ++i) {
    bound[i] = distance(faces[i]);
    if (bound[i] < 0 && kind != 4) return false;
    if (bound[i] >= 0) bound[i] = std::max(bound[i], (offset > 0 ? 0.95 : kFacetShare) * in.facetDistance);
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
      if (bound[i] < 0) continue;
      const double d = distance(faces[i]);
      if (d < 0 || d > bound[i]) return false;
    }
    volumeChange(change);
    for (size_t l = 0; l < change.size(); ++l)
      if (!m.moveFits(l, change[l])) return false;
    return in.boxPlanes(m.pts[size_t(v)]) == box;
  };
  if (!smoothVertex(m, v, &c)) return false;
  volumeChange(change);
  for (size_t l = 0; l < change.size(); ++l) m.bookMove(l, change[l]);
  return true;
}

bool starWithinFacetDistance(const Editor& m, const OptimizeInterfaces& in, int32_t v) {
  std::vector<int> materials;
  std::vector<InterfaceFace> faces;
  vertexInterfaces(m, in, v, materials, faces);
  for (const auto& f : faces) {
    const double d = centroidDistance(m, in, f);
    if (d < 0 || d > in.facetDistance) return false;
  }
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
        near = d >= 0 && d <= in.facetDistance;
      }
      const double v = m.volume(t);
      if (!near || !m.transferFits(size_t(own), size_t(other), v))
        continue;
      // t joins the other material: (a, b) is then inside it, and removing that edge must help.
      m.relabel(t, other);
      if (removeEdge(m, t, ab[0], ab[1], fresh)) {
        m.transfer(size_t(own), size_t(other), v);
        return true;
      }
      m.relabel(t, own);
    }
  return false;
}

bool relabelFlatTet(Editor& m, uint32_t t, const OptimizeInterfaces& in, double tolerance,
                    std::vector<uint32_t>& fresh) {
  const int own = m.labels[t];
  // Thinner than the tolerance (the peel distance) or the facet distance, whichever is larger:
  // the faces that become interfaces then lie that close to the interface faces they replace.
  const double thickness = m.thickness(t);
  if (tolerance <= 0 || m.perLabel[size_t(own)] <= 1 ||
      !(thickness <= std::max(tolerance, in.facetDistance)))
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
    // materials, the pair is not the leading one), the tet may still go when it is thinner than
    // the facet distance: its faces lie that close to the interface faces they replace.
    const bool sliver = thickness <= in.facetDistance;
    bool near = true;
    for (int k = 0; k < 4 && near; ++k) {
      const int l = m.labels[size_t(nb[k])];
      if (l == other) continue;
      const InterfaceFace f{m.face(t, k), std::min(l, other), std::max(l, other), {0, 0, 0}};
      const double d = centroidDistance(m, in, f);
      near = d >= 0 ? d <= in.facetDistance : sliver;
    }
    if (!near ||
        !m.transferFits(size_t(own), size_t(other), v))
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
    m.transfer(size_t(own), size_t(other), v);
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
    if (!moveOntoInterface(field, a, b, x)) return false;
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
