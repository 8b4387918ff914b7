// SPDX-License-Identifier: GPL-3.0-or-later
#include <CGAL/box_intersection_d.h>
#include <CGAL/intersections.h>
#include <femesher/RunContext.h>
#include <femesher/UnionFind.h>
#include <femesher/stages/internal/LocalDelaunayBuilder.h>


namespace femesher {

namespace ldt {

namespace {

using Box = CGAL::Box_intersection_d::Box_with_info_d<double, 3, int32_t>;

/// Exact test: do triangles A and B (vertex ids into pos) intersect other than in what they share?
bool trianglesIntersect(const Triple& A, const Triple& B, const std::vector<Vec3>& pos) {
  auto pt = [&](int32_t i) {
    return K::Point_3(pos[size_t(i)][0], pos[size_t(i)][1], pos[size_t(i)][2]);
  };
  int shared = 0;
  int sa[3] = {-1, -1, -1}, sb[3] = {-1, -1, -1};  // index in B of A's vertex k, and vice versa
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      if (A[i] == B[j]) {
        sa[i] = j;
        sb[j] = i;
        ++shared;
      }
  if (shared == 3) return true;  // the same triangle twice
  const K::Triangle_3 ta(pt(A[0]), pt(A[1]), pt(A[2])), tb(pt(B[0]), pt(B[1]), pt(B[2]));
  if (shared == 0) return CGAL::do_intersect(ta, tb);
  if (shared == 2) {
    int u = -1, v = -1, wa = -1, wb = -1;
    for (int i = 0; i < 3; ++i) {
      if (sa[i] < 0)
        wa = A[i];
      else if (u < 0)
        u = A[i];
      else
        v = A[i];
      if (sb[i] < 0) wb = B[i];
    }
    const K::Point_3 pu = pt(u), pv = pt(v), pa = pt(wa), pb = pt(wb);
    if (!CGAL::coplanar(pu, pv, pa, pb)) return false;
    if (CGAL::collinear(pu, pv, pa) || CGAL::collinear(pu, pv, pb)) return true;  // degenerate
    return CGAL::coplanar_orientation(pu, pv, pa, pb) == CGAL::POSITIVE;          // folded onto A
  }
  // One shared vertex: the intersection, if more than the vertex, ends on an opposite edge.
  Triple oa{}, ob{};
  int ka = 0, kb = 0;
  for (int i = 0; i < 3; ++i) {
    if (sa[i] < 0) oa[size_t(ka++)] = A[i];
    if (sb[i] < 0) ob[size_t(kb++)] = B[i];
  }
  const K::Segment_3 ea(pt(oa[0]), pt(oa[1])), eb(pt(ob[0]), pt(ob[1]));
  return CGAL::do_intersect(ea, tb) || CGAL::do_intersect(eb, ta);
}

}  // namespace

/// For every material, the edges used an odd number of times by the triangles bounding it.
std::vector<std::pair<uint16_t, uint64_t>> oddEdges(
    const std::vector<Triple>& triangles, const std::vector<std::pair<uint16_t, uint16_t>>& pairs) {
  std::vector<std::pair<uint16_t, uint64_t>> uses;
  uses.reserve(triangles.size() * 6);
  for (size_t t = 0; t < triangles.size(); ++t)
    for (uint16_t m : {pairs[t].first, pairs[t].second}) {
      if (m == 0) continue;
      for (int e = 0; e < 3; ++e)
        uses.emplace_back(m, edgeKey(triangles[t][e], triangles[t][(e + 1) % 3]));
    }
  std::sort(uses.begin(), uses.end());
  std::vector<std::pair<uint16_t, uint64_t>> odd;
  for (size_t i = 0; i < uses.size();) {
    size_t j = i;
    while (j < uses.size() && uses[j] == uses[i]) ++j;
    if ((j - i) % 2) odd.push_back(uses[i]);
    i = j;
  }
  return odd;
}

/// Pairs (a, b), a in `suspects`, b any triangle, that intersect (each unordered pair once).
std::vector<std::pair<int32_t, int32_t>> intersectingPairs(const std::vector<Triple>& tris,
                                                           const std::vector<char>& suspect,
                                                           const std::vector<Vec3>& pos) {
  std::vector<Box> all, sus;
  all.reserve(tris.size());
  for (size_t t = 0; t < tris.size(); ++t) {
    CGAL::Bbox_3 b;
    for (int32_t v : tris[t]) {
      const Vec3& p = pos[size_t(v)];
      b += CGAL::Bbox_3(p[0], p[1], p[2], p[0], p[1], p[2]);
    }
    all.emplace_back(b, int32_t(t));
    if (suspect[t]) sus.emplace_back(b, int32_t(t));
  }
  std::vector<std::pair<int32_t, int32_t>> out;
  CGAL::box_intersection_d(sus.begin(), sus.end(), all.begin(), all.end(),
                           [&](const Box& a, const Box& b) {
                             const int32_t x = a.info(), y = b.info();
                             if (x == y || (suspect[size_t(y)] && y < x)) return;
                             if (trianglesIntersect(tris[size_t(x)], tris[size_t(y)], pos))
                               out.emplace_back(std::min(x, y), std::max(x, y));
                           });
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

void Builder::restrictedClosure() {
  // Entries: every alive local triangle and every restricted one, keyed by vertices and patch.
  struct Entry {
    Triple v;  // oriented
    uint32_t patch;
    bool inL = false, inR = false;
    Source source = kRestricted;
  };
  std::vector<Entry> entries;
  std::unordered_map<TriKey, int32_t, TriKeyHash> index;
  for (const Tri& t : tris_) {
    if (!t.alive) continue;
    index.emplace(TriKey{sorted(t.v), t.patch}, int32_t(entries.size()));
    entries.push_back({t.v, t.patch, true, false, t.source});
  }
  for (const RTri& r : rtris_) {
    auto [it, fresh] = index.emplace(TriKey{sorted(r.v), r.patch}, int32_t(entries.size()));
    if (fresh)
      entries.push_back({r.v, r.patch, false, true, kRestricted});
    else
      entries[size_t(it->second)].inR = true;
  }
  const size_t m = entries.size();
  auto differs = [&](size_t e) { return entries[e].inL != entries[e].inR; };
  // Pair, at every edge, a local and a restricted triangle on the same side of the same patch;
  // everything else at the edge is grouped.
  struct Inc {
    uint64_t edge;
    uint32_t patch;
    int side;
    int32_t entry;
    bool operator<(const Inc& o) const {
      if (edge != o.edge) return edge < o.edge;
      if (patch != o.patch) return patch < o.patch;
      if (side != o.side) return side < o.side;
      return entry < o.entry;
    }
  };
  std::vector<Inc> inc;
  for (size_t e = 0; e < m; ++e) {
    if (!differs(e)) continue;
    const Triple& v = entries[e].v;
    for (int k = 0; k < 3; ++k) {
      const int32_t a = v[size_t(k)], b = v[size_t((k + 1) % 3)];
      inc.push_back({edgeKey(a, b), entries[e].patch, a < b ? 1 : -1, int32_t(e)});
    }
  }
  std::sort(inc.begin(), inc.end());
  UnionFind uf(m);
  std::unordered_map<uint64_t, int32_t> leftover;  // edge -> an entry of its leftover group
  for (size_t i = 0; i < inc.size();) {
    size_t j = i;
    while (j < inc.size() && inc[j].edge == inc[i].edge) ++j;
    int32_t rest = -1;
    for (size_t s = i; s < j;) {
      size_t t = s;
      while (t < j && inc[t].patch == inc[s].patch && inc[t].side == inc[s].side) ++t;
      int nl = 0, nr = 0;
      for (size_t x = s; x < t; ++x) (entries[size_t(inc[x].entry)].inL ? nl : nr)++;
      if (nl == 1 && nr == 1) {
        uf.unite(inc[s].entry, inc[s + 1].entry);
      } else {
        for (size_t x = s; x < t; ++x) {
          if (rest >= 0)
            uf.unite(rest, inc[x].entry);
          else
            rest = inc[x].entry;
        }
      }
      s = t;
    }
    if (rest >= 0) leftover[inc[i].edge] = rest;
    i = j;
  }
  std::vector<char> swapped(m, 0), needed(m, 0);
  auto currentSet = [&](std::vector<Triple>& tris,
                        std::vector<std::pair<uint16_t, uint16_t>>& pairs,
                        std::vector<int32_t>& which) {
    tris.clear();
    pairs.clear();
    which.clear();
    for (size_t e = 0; e < m; ++e) {
      const Entry& en = entries[e];
      const bool on = en.inL && en.inR ? true
                                       : (en.inL ? !swapped[size_t(uf.find(int32_t(e)))]
                                                 : swapped[size_t(uf.find(int32_t(e)))] != 0);
      if (!on) continue;
      tris.push_back(en.v);
      pairs.push_back(patchPairs_[en.patch]);
      which.push_back(int32_t(e));
    }
  };
  std::vector<Triple> tris;
  std::vector<std::pair<uint16_t, uint16_t>> pairs;
  std::vector<int32_t> which;
  currentSet(tris, pairs, which);
  // Open edges: swap the component of the leftover group at each.
  for (const auto& [mat, edge] : oddEdges(tris, pairs)) {
    auto it = leftover.find(edge);
    if (it != leftover.end()) needed[size_t(uf.find(it->second))] = 1;
  }
  // Self-intersections: kept triangles that are not restricted facets (those cannot cross each
  // other) against all; a vertex triple in two patches counts as one. The first test is on the
  // local surface alone; then swap, retest, until nothing new has to be swapped.
  for (int round = 0; round < 50; ++round) {
    ctx_.checkCancel();
    std::vector<char> suspect(tris.size(), 0);
    for (size_t t = 0; t < tris.size(); ++t) suspect[t] = !entries[size_t(which[t])].inR;
    const auto pairsX = intersectingPairs(tris, suspect, pos_);
    if (round == 0) res_.selfIntersections = pairsX.size();
    res_.selfIntersectionsAfter = pairsX.size();
    for (const auto& [x, y] : pairsX)
      for (int32_t t : {x, y}) {
        const size_t e = size_t(which[size_t(t)]);
        if (differs(e)) needed[size_t(uf.find(int32_t(e)))] = 1;
      }
    bool any = false;
    for (size_t r = 0; r < m; ++r)
      if (needed[r] && !swapped[r]) {
        swapped[r] = 1;
        any = true;
      }
    if (!any) break;
    currentSet(tris, pairs, which);
  }
  // Write the result back into the builder's triangle list (provenance kept).
  std::vector<Tri> out;
  for (size_t e = 0; e < m; ++e) {
    const Entry& en = entries[e];
    const bool sw = swapped[size_t(uf.find(int32_t(e)))] != 0;
    if (en.inL && (en.inR || !sw))
      out.push_back({en.v, en.patch, en.source, true});
    else if (!en.inL && sw)
      out.push_back({en.v, en.patch, kRestricted, true});
    if (en.inL && !en.inR && sw) ++res_.replacedTriangles;
  }
  for (size_t r = 0; r < m; ++r)
    if (swapped[r] && uf.find(int32_t(r)) == int32_t(r)) ++res_.restrictedComponents;
  tris_ = std::move(out);
}

}  // namespace ldt

}  // namespace femesher
