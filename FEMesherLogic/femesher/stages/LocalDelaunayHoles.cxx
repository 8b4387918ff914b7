// SPDX-License-Identifier: GPL-3.0-or-later
#include <CGAL/Polygon_mesh_processing/triangulate_hole.h>
#include <CGAL/intersections.h>
#include <femesher/stages/internal/LocalDelaunayBuilder.h>

namespace femesher {

namespace ldt {

bool Builder::planarFill(const std::vector<int32_t>& loop, uint32_t patch,
                         std::vector<Triple>& fill) const {
  const size_t k = loop.size();
  // Plane of the loop: Newell normal, which must agree with the patch normals.
  Vec3 newell{0, 0, 0}, ref{0, 0, 0};
  for (size_t i = 0; i < k; ++i) {
    const Vec3& a = pos_[size_t(loop[i])];
    const Vec3& b = pos_[size_t(loop[(i + 1) % k])];
    newell = add(newell, {(a[1] - b[1]) * (a[2] + b[2]), (a[2] - b[2]) * (a[0] + b[0]),
                          (a[0] - b[0]) * (a[1] + b[1])});
    ref = add(ref, vertexNormal(loop[i], patch));
  }
  if (norm(newell) == 0 || dot(normalized(newell), normalized(ref)) < 0.3) return false;
  const Frame f = frameOf(normalized(newell));
  std::vector<K::Point_2> q(k);
  for (size_t i = 0; i < k; ++i) {
    const Vec3 d = sub(pos_[size_t(loop[i])], pos_[size_t(loop[0])]);
    q[i] = K::Point_2(dot(d, f.t1), dot(d, f.t2));
  }
  // Simple polygon only (a crossing would need a new vertex).
  for (size_t i = 0; i < k; ++i)
    for (size_t j = i + 1; j < k; ++j) {
      const size_t i2 = (i + 1) % k, j2 = (j + 1) % k;
      if (j == i2 || i == j2) {  // adjacent: must not fold back onto each other
        const K::Point_2& s = j == i2 ? q[j] : q[i];
        const K::Point_2& o1 = j == i2 ? q[i] : q[i2];
        const K::Point_2& o2 = j == i2 ? q[j2] : q[j];
        if (CGAL::orientation(o1, s, o2) == CGAL::COLLINEAR &&
            (o1.x() - s.x()) * (o2.x() - s.x()) + (o1.y() - s.y()) * (o2.y() - s.y()) > 0)
          return false;
        continue;
      }
      if (CGAL::do_intersect(K::Segment_2(q[i], q[i2]), K::Segment_2(q[j], q[j2]))) return false;
    }
  Cdt dt;
  std::vector<Cdt::Vertex_handle> hv(k);
  for (size_t i = 0; i < k; ++i) {
    hv[i] = dt.insert(q[i]);
    hv[i]->info().id = int32_t(i);
  }
  if (dt.number_of_vertices() != k) return false;
  for (size_t i = 0; i < k; ++i) dt.insert_constraint(hv[i], hv[(i + 1) % k]);
  if (dt.number_of_vertices() != k) return false;
  // Inside = not reachable from the infinite face without crossing the loop.
  for (auto fh = dt.all_faces_begin(); fh != dt.all_faces_end(); ++fh) fh->info() = 0;
  std::vector<Cdt::Face_handle> stack{dt.infinite_face()};
  dt.infinite_face()->info() = 1;
  while (!stack.empty()) {
    auto fh = stack.back();
    stack.pop_back();
    for (int e = 0; e < 3; ++e) {
      auto nb = fh->neighbor(e);
      if (nb->info() == 0 && !dt.is_constrained({fh, e})) {
        nb->info() = 1;
        stack.push_back(nb);
      }
    }
  }
  fill.clear();
  for (auto fh = dt.finite_faces_begin(); fh != dt.finite_faces_end(); ++fh)
    if (fh->info() == 0)
      fill.push_back({loop[size_t(fh->vertex(0)->info().id)],
                      loop[size_t(fh->vertex(1)->info().id)],
                      loop[size_t(fh->vertex(2)->info().id)]});
  return fill.size() == k - 2;
}

bool Builder::spatialFill(const std::vector<int32_t>& loop, uint32_t patch,
                          std::vector<Triple>& fill) const {
  // Minimum-weight triangulation of the 3-D polygon (largest dihedral angle, then area; CGAL),
  // each loop edge's neighbouring triangle given so the fill does not fold onto it.
  const size_t k = loop.size();
  std::vector<K::Point_3> pts, third;
  for (size_t i = 0; i < k; ++i) {
    const int32_t a = loop[i], b = loop[(i + 1) % k];
    const Vec3& p = pos_[size_t(a)];
    pts.emplace_back(p[0], p[1], p[2]);
    Vec3 apex;
    auto it = edges_.find({edgeKey(a, b), patch});
    if (it != edges_.end() && it->second.count >= 1) {
      const Triple& t = tris_[size_t(it->second.t[0])].v;
      apex = pos_[size_t(t[0] != a && t[0] != b ? t[0] : (t[1] != a && t[1] != b ? t[1] : t[2]))];
    } else {  // an unused rim link: the patch lies away from the line's third material
      const Vec3 e = sub(pos_[size_t(b)], p);
      Vec3 g{0, 0, 0};
      for (const Link& l : links_[size_t(a)])
        if (l.other == b && tripleHasPatch(l.triple, patch))
          g = add(gradientMm(thirdLabel(l.triple, patch), a),
                  gradientMm(thirdLabel(l.triple, patch), b));
      g = sub(g, scale(normalized(e), dot(g, normalized(e))));
      apex = add(add(p, scale(e, 0.5)), scale(normalized(g), 0.5 * norm(e)));
    }
    third.emplace_back(apex[0], apex[1], apex[2]);
  }
  struct Out {
    int a, b, c;
    Out(int x, int y, int z) : a(x), b(y), c(z) {}
  };
  std::vector<Out> out;
  CGAL::Polygon_mesh_processing::triangulate_hole_polyline(
      pts, third, std::back_inserter(out),
      CGAL::parameters::use_delaunay_triangulation(true).do_not_use_cubic_algorithm(k > 80));
  if (out.size() != k - 2) return false;
  fill.clear();
  for (const Out& o : out) {
    if (o.a < 0 || o.b < 0 || o.c < 0 || size_t(std::max({o.a, o.b, o.c})) >= k) return false;
    fill.push_back({loop[size_t(o.a)], loop[size_t(o.b)], loop[size_t(o.c)]});
  }
  return true;
}

bool Builder::fillLoop(const std::vector<int32_t>& loop, uint32_t patch) {
  const size_t k = loop.size();
  if (k < 3 || k > 300) return false;
  std::vector<Triple> fill;
  if (k == 3)
    fill.push_back({loop[0], loop[1], loop[2]});
  else if (!planarFill(loop, patch, fill) && !spatialFill(loop, patch, fill))
    return false;
  std::sort(fill.begin(), fill.end());
  std::vector<int32_t> added;
  for (const Triple& v : fill) {
    if (!canAdd(v, patch, false)) {
      for (int32_t t : added) removeTri(t);
      tris_.resize(tris_.size() - added.size());
      return false;
    }
    added.push_back(addTri(v, patch, kLoopFill));
  }
  return true;
}

void Builder::fillHoles() {
  const std::vector<HoleEdge> hole = holeEdges();
  for (size_t h0 = 0; h0 < hole.size();) {
    const uint32_t patch = hole[h0].patch;
    size_t h1 = h0;
    while (h1 < hole.size() && hole[h1].patch == patch) ++h1;
    const std::vector<std::vector<int32_t>> loops = traceLoops(hole.data() + h0, hole.data() + h1);
    res_.holeLoops += loops.size();
    for (const auto& loop : loops)
      if (fillLoop(loop, patch)) ++res_.holesFilled;
    h0 = h1;
  }
}

std::vector<Builder::HoleEdge> Builder::holeEdges() {
  std::vector<HoleEdge> hole;
  for (const auto& [key, r] : edges_) {
    if (r.count != 1) continue;
    const int32_t a = int32_t(key.edge >> 32), b = int32_t(key.edge & 0xFFFFFFFFu);
    if (isRim(a, b, key.patch)) continue;
    const int d = direction(tris_[size_t(r.t[0])].v, a, b);
    hole.push_back(d > 0 ? HoleEdge{key.patch, b, a, false} : HoleEdge{key.patch, a, b, false});
  }
  // Rim links a patch does not use yet, where the patch is present at one of their ends.
  for (size_t x = 0; x < n_; ++x)
    for (const Link& l : links_[x]) {
      if (l.other < int32_t(x)) continue;
      const auto& t = triples_[l.triple];
      for (int p = 0; p < 3; ++p)
        for (int q = p + 1; q < 3; ++q) {
          auto it = patchId_.find({t[size_t(p)], t[size_t(q)]});
          if (it == patchId_.end()) continue;
          const uint32_t patch = it->second;
          if (edgeCount(int32_t(x), l.other, patch) != 0) continue;
          const int sx = slotOf(int32_t(x), patch), sy = slotOf(l.other, patch);
          if (sx < 0 || sy < 0 || (fan_[size_t(sx)].empty() && fan_[size_t(sy)].empty())) continue;
          hole.push_back({patch, int32_t(x), l.other, true});
        }
    }
  // Open edges a patch that does not use them may have to: an edge open for exactly two materials
  // a, b (the outside counted) -> patch (a,b); an edge between two junction particles sharing a
  // label triple that holds an open material -> each patch of that triple (a piece of triple line
  // the links missed). Either direction.
  {
    std::vector<std::pair<uint16_t, uint64_t>> uses;
    for (const Tri& t : tris_) {
      if (!t.alive) continue;
      for (uint16_t m : {patchPairs_[t.patch].first, patchPairs_[t.patch].second})
        for (int e = 0; e < 3; ++e)
          uses.emplace_back(m, edgeKey(t.v[size_t(e)], t.v[size_t((e + 1) % 3)]));
    }
    std::sort(uses.begin(), uses.end());
    std::map<uint64_t, std::vector<uint16_t>> odd;
    for (size_t i = 0; i < uses.size();) {
      size_t j = i;
      while (j < uses.size() && uses[j] == uses[i]) ++j;
      if ((j - i) % 2) odd[uses[i].second].push_back(uses[i].first);
      i = j;
    }
    std::vector<uint32_t> patches;
    for (const auto& [e, ms] : odd) {
      const int32_t a = int32_t(e >> 32), b = int32_t(e & 0xFFFFFFFFu);
      patches.clear();
      if (ms.size() == 2) {
        auto it = patchId_.find({std::min(ms[0], ms[1]), std::max(ms[0], ms[1])});
        if (it != patchId_.end()) patches.push_back(it->second);
      }
      if (P_[size_t(a)].junction >= 0 && P_[size_t(b)].junction >= 0) {
        const std::vector<uint32_t> ta = triplesOf(a), tb = triplesOf(b);
        for (uint32_t t : ta) {
          if (std::find(tb.begin(), tb.end(), t) == tb.end()) continue;
          const auto& lab = triples_[t];
          bool holdsOpen = false;
          for (uint16_t m : ms) holdsOpen = holdsOpen || m == lab[0] || m == lab[1] || m == lab[2];
          if (!holdsOpen) continue;
          for (int p = 0; p < 3; ++p)
            for (int q = p + 1; q < 3; ++q) {
              auto it = patchId_.find({lab[size_t(p)], lab[size_t(q)]});
              if (it != patchId_.end()) patches.push_back(it->second);
            }
        }
      }
      std::sort(patches.begin(), patches.end());
      patches.erase(std::unique(patches.begin(), patches.end()), patches.end());
      for (uint32_t patch : patches) {
        const int sa = slotOf(a, patch), sb = slotOf(b, patch);
        if (sa < 0 || sb < 0 || edgeCount(a, b, patch) != 0 || isRim(a, b, patch)) continue;
        if (fan_[size_t(sa)].empty() && fan_[size_t(sb)].empty()) continue;
        hole.push_back({patch, a, b, true});
      }
    }
  }
  std::sort(hole.begin(), hole.end());
  hole.erase(std::unique(hole.begin(), hole.end(),
                         [](const HoleEdge& a, const HoleEdge& b) {
                           return a.patch == b.patch && a.from == b.from && a.to == b.to &&
                                  a.rim == b.rim;
                         }),
             hole.end());
  return hole;
}

std::vector<std::vector<int32_t>> Builder::traceLoops(const HoleEdge* first,
                                                      const HoleEdge* last) const {
  const uint32_t patch = first->patch;
  // from -> (to, flag); both directions of an unused rim link share one flag.
  std::map<int32_t, std::vector<std::pair<int32_t, size_t>>> out;
  const size_t n = size_t(last - first);
  std::vector<char> usedFlag(n, 0), undirected(n, 0);
  for (size_t h = 0; h < n; ++h) {
    out[first[h].from].push_back({first[h].to, h});
    if (first[h].rim) out[first[h].to].push_back({first[h].from, h});
    undirected[h] = first[h].rim;
  }
  // Each loop starts on an unused directed edge and is the first simple cycle back to its start
  // found depth first, the smallest turn in the tangent plane tried first (the tightest loop);
  // dead ends are backtracked, within a step budget.
  std::vector<std::vector<int32_t>> loops;
  auto options = [&](int32_t prev, int32_t cur) {
    std::vector<std::pair<double, size_t>> opt;  // (turn, index in out[cur])
    auto it = out.find(cur);
    const int s = slotOf(cur, patch);
    if (it == out.end() || s < 0) return opt;
    const Frame& f = frame_[size_t(s)];
    const double back = angleIn(f, sub(pos_[size_t(prev)], pos_[size_t(cur)]));
    for (size_t o = 0; o < it->second.size(); ++o) {
      if (usedFlag[it->second[o].second]) continue;
      double turn =
          wrapAngle(back - angleIn(f, sub(pos_[size_t(it->second[o].first)], pos_[size_t(cur)])));
      if (turn == 0) turn = kTwoPi;
      opt.emplace_back(turn, o);
    }
    std::sort(opt.begin(), opt.end());
    return opt;
  };
  struct Step {
    int32_t v;
    std::vector<std::pair<double, size_t>> next;
    size_t k;
    size_t via;  // flag of the edge that led here
  };
  for (auto& [start, list] : out) {
    for (size_t li = 0; li < list.size(); ++li) {
      if (usedFlag[list[li].second] || undirected[list[li].second]) continue;
      usedFlag[list[li].second] = 1;
      std::vector<Step> stack;
      std::unordered_set<int32_t> onPath{start, list[li].first};
      stack.push_back({list[li].first, options(start, list[li].first), 0, list[li].second});
      bool closed = false;
      for (size_t steps = 0; !stack.empty() && steps < 20000; ++steps) {
        Step& top = stack.back();
        if (top.k >= top.next.size()) {  // dead end: back up
          if (stack.size() > 1) usedFlag[top.via] = 0;
          onPath.erase(top.v);
          stack.pop_back();
          continue;
        }
        const auto [to, flag] = out[top.v][top.next[top.k++].second];
        if (usedFlag[flag]) continue;
        if (to == start) {
          if (stack.size() < 2) continue;
          usedFlag[flag] = 1;
          closed = true;
          break;
        }
        if (onPath.count(to) || stack.size() >= 300) continue;
        usedFlag[flag] = 1;
        onPath.insert(to);
        const int32_t from = top.v;
        stack.push_back({to, options(from, to), 0, flag});
      }
      if (closed) {
        std::vector<int32_t> loop{start};
        for (const Step& st : stack) loop.push_back(st.v);
        loops.push_back(std::move(loop));
      } else {
        for (size_t k = 1; k < stack.size(); ++k) usedFlag[stack[k].via] = 0;
      }
    }
  }
  return loops;
}

}  // namespace ldt

}  // namespace femesher
