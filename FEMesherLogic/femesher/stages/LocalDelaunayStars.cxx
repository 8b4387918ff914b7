// SPDX-License-Identifier: GPL-3.0-or-later
#include <CGAL/intersections.h>
#include <femesher/Parallel.h>
#include <femesher/RunContext.h>
#include <femesher/stages/internal/LocalDelaunayBuilder.h>

namespace femesher {

namespace ldt {

namespace {

/// 2 x inradius / circumradius (1 for the equilateral triangle, 0 for a degenerate one).
double shapeQuality(const Vec3& p0, const Vec3& p1, const Vec3& p2) {
  const double a = norm(sub(p1, p2)), b = norm(sub(p0, p2)), c = norm(sub(p0, p1));
  const double area = 0.5 * norm(cross(sub(p1, p0), sub(p2, p0)));
  const double denom = (a + b + c) * a * b * c;
  return denom > 0 ? 16.0 * area * area / denom : 0.0;
}

}  // namespace

void Builder::star(int32_t i, uint32_t patch, const Frame& fr, std::vector<uint32_t>& cand,
                   std::vector<TriKey>& out) const {
  auto agrees = [&](uint32_t q) {
    const int s = slotOf(int32_t(q), patch);
    return s >= 0 && dot(frame_[size_t(s)].n, fr.n) >= prm_.normalAgreement;
  };
  // Local spacing: the sixth-nearest agreeing Delaunay neighbour; candidates lie within
  // `candidateRadius` times that (a flat, cospherical sample has Delaunay edges of any length).
  std::vector<double> d2;
  for (uint32_t k = off_[size_t(i)]; k < off_[size_t(i) + 1]; ++k)
    if (agrees(adj_[k])) {
      const Vec3 d = sub(pos_[adj_[k]], pos_[size_t(i)]);
      d2.push_back(dot(d, d));
    }
  if (d2.empty()) return;
  const size_t kth = std::min<size_t>(5, d2.size() - 1);
  std::nth_element(d2.begin(), d2.begin() + long(kth), d2.end());
  const double r2 = d2[kth] * prm_.candidateRadius * prm_.candidateRadius;
  auto within = [&](uint32_t q) {
    const Vec3 d = sub(pos_[q], pos_[size_t(i)]);
    return dot(d, d) <= r2;
  };
  auto gather = [&](bool twoRing) {
    cand.clear();
    for (uint32_t k = off_[size_t(i)]; k < off_[size_t(i) + 1]; ++k) {
      const uint32_t q = adj_[k];
      if (!within(q)) continue;
      if (!agrees(q)) continue;
      cand.push_back(q);
      if (!twoRing) continue;
      for (uint32_t k2 = off_[q]; k2 < off_[q + 1]; ++k2)
        if (adj_[k2] != uint32_t(i) && within(adj_[k2]) && agrees(adj_[k2]))
          cand.push_back(adj_[k2]);
    }
    for (const Link& l : links_[size_t(i)])
      if (tripleHasPatch(l.triple, patch) && agrees(uint32_t(l.other)))
        cand.push_back(uint32_t(l.other));
    std::sort(cand.begin(), cand.end());
    cand.erase(std::unique(cand.begin(), cand.end()), cand.end());
  };
  if (prm_.candidateRings == 2) {
    gather(true);
    starOf(i, patch, fr, cand, out);
  } else {
    gather(false);
    starOf(i, patch, fr, cand, out);
  }
}

/// Triangulates p's candidates in its tangent plane and appends p's star. False when p lies on
/// the hull of the projected candidates other than along a rim link of the patch.
bool Builder::starOf(int32_t i, uint32_t patch, const Frame& fr, const std::vector<uint32_t>& cand,
                     std::vector<TriKey>& out) const {
  if (cand.size() < 2) return false;
  Cdt dt;
  std::vector<Cdt::Vertex_handle> hv(cand.size());
  auto project = [&](uint32_t q) {
    const Vec3 d = sub(pos_[q], pos_[size_t(i)]);
    return K::Point_2(dot(d, fr.t1), dot(d, fr.t2));
  };
  const Cdt::Vertex_handle vi = dt.insert(K::Point_2(0, 0));
  vi->info().id = i;
  for (size_t k = 0; k < cand.size(); ++k) {
    hv[k] = dt.insert(project(cand[k]));
    if (hv[k]->info().id < 0) hv[k]->info().id = int32_t(cand[k]);
  }
  // Rim links as constraints (never two that cross: that would add a vertex).
  std::vector<std::pair<Cdt::Vertex_handle, Cdt::Vertex_handle>> segs;
  auto handleOf = [&](int32_t q) -> Cdt::Vertex_handle {
    if (q == i) return vi;
    auto it = std::lower_bound(cand.begin(), cand.end(), uint32_t(q));
    if (it == cand.end() || *it != uint32_t(q)) return Cdt::Vertex_handle();
    return hv[size_t(it - cand.begin())];
  };
  auto crosses = [&](Cdt::Vertex_handle a, Cdt::Vertex_handle b) {
    for (const auto& [c, d] : segs) {
      const int shared = (a == c) + (a == d) + (b == c) + (b == d);
      if (shared == 2) return true;
      const K::Point_2 &pa = a->point(), &pb = b->point(), &pc = c->point(), &pd = d->point();
      if (shared == 0) {
        if (CGAL::do_intersect(K::Segment_2(pa, pb), K::Segment_2(pc, pd))) return true;
        continue;
      }
      const K::Point_2& s = (a == c || a == d) ? pa : pb;
      const K::Point_2& o1 = (a == c || a == d) ? pb : pa;
      const K::Point_2& o2 = (c == a || c == b) ? pd : pc;
      if (CGAL::orientation(s, o1, o2) == CGAL::COLLINEAR &&
          (o1.x() - s.x()) * (o2.x() - s.x()) + (o1.y() - s.y()) * (o2.y() - s.y()) > 0)
        return true;
    }
    return false;
  };
  for (size_t k = 0; k <= cand.size(); ++k) {
    const int32_t x = k < cand.size() ? int32_t(cand[k]) : i;
    for (const Link& l : links_[size_t(x)]) {
      if (l.other < x || !tripleHasPatch(l.triple, patch)) continue;
      const Cdt::Vertex_handle a = handleOf(x), b = handleOf(l.other);
      if (a == Cdt::Vertex_handle() || b == Cdt::Vertex_handle() || a == b) continue;
      if (a->info().id != x || b->info().id != l.other || crosses(a, b)) continue;
      dt.insert_constraint(a, b);
      segs.emplace_back(a, b);
    }
  }
  if (vi->info().id != i || dt.dimension() < 2) return false;
  bool closed = true;
  auto fc = dt.incident_faces(vi), done = fc;
  if (fc == nullptr) return false;
  do {
    if (dt.is_infinite(fc)) {  // p on the hull: along a rim link is fine
      const int k = fc->index(vi);
      const Cdt::Vertex_handle a = fc->vertex((k + 1) % 3), b = fc->vertex((k + 2) % 3);
      const Cdt::Vertex_handle o = dt.is_infinite(a) ? b : a;
      if (!isRim(i, o->info().id, patch)) closed = false;
      continue;
    }
    const Triple t{fc->vertex(0)->info().id, fc->vertex(1)->info().id, fc->vertex(2)->info().id};
    if (t[0] < 0 || t[1] < 0 || t[2] < 0) continue;
    if (alongOneLine(t, patch)) continue;
    bool far = false;
    for (int e = 0; e < 3 && !far; ++e)
      far = farSideOfRim(t[size_t(e)], t[size_t((e + 1) % 3)], t[size_t((e + 2) % 3)], patch);
    if (far) continue;
    out.push_back({sorted(t), patch});
  } while (++fc != done);
  return closed;
}

std::vector<Builder::Candidate> Builder::computeCandidates() {
  const int threads = resolveThreads(ctx_.threads());
  const int chunks = threads * 8;
  std::vector<std::vector<TriKey>> found(static_cast<size_t>(chunks));
  parallelFor(
      n_, threads,
      [&](size_t b, size_t e, int chunk) {
        std::vector<uint32_t> cand;
        for (size_t i = b; i < e; ++i) {
          if ((i & 0x3FF) == 0 && ctx_.isCanceled()) return;
          for (uint32_t s = memOff_[i]; s < memOff_[i + 1]; ++s)
            star(int32_t(i), memPatch_[s], frame_[s], cand, found[size_t(chunk)]);
        }
      },
      chunks);
  ctx_.checkCancel();
  std::vector<TriKey> all;
  size_t total = 0;
  for (const auto& f : found) total += f.size();
  all.reserve(total);
  for (auto& f : found) {
    all.insert(all.end(), f.begin(), f.end());
    std::vector<TriKey>().swap(f);
  }
  std::sort(all.begin(), all.end());
  std::vector<Candidate> cands;
  for (size_t i = 0; i < all.size();) {
    size_t j = i;
    while (j < all.size() && all[j] == all[i]) ++j;
    const Triple& v = all[i].v;
    cands.push_back({all[i], int(j - i), rset_.count(all[i]) > 0,
                     shapeQuality(pos_[size_t(v[0])], pos_[size_t(v[1])], pos_[size_t(v[2])])});
    i = j;
  }
  res_.starTriangles = cands.size();
  return cands;
}

Triple Builder::orient(Triple v, uint32_t patch) const {
  const Vec3 nrm = cross(sub(pos_[size_t(v[1])], pos_[size_t(v[0])]),
                         sub(pos_[size_t(v[2])], pos_[size_t(v[0])]));
  const Vec3 ref =
      add(add(vertexNormal(v[0], patch), vertexNormal(v[1], patch)), vertexNormal(v[2], patch));
  if (dot(nrm, ref) < 0) std::swap(v[1], v[2]);
  return v;
}

/// Angular sector of triangle (u, v, w) (counter-clockwise about the frame normal) at corner u:
/// from the direction of v, `width` radians counter-clockwise. False when the triangle is flipped
/// or degenerate seen from u.
bool Builder::sector(int32_t u, int32_t v, int32_t w, const Frame& f, double& start,
                     double& width) const {
  start = angleIn(f, sub(pos_[size_t(v)], pos_[size_t(u)]));
  const double end = angleIn(f, sub(pos_[size_t(w)], pos_[size_t(u)]));
  width = wrapAngle(end - start);
  return width > 1e-6 && width < kPi - 1e-6;
}

bool Builder::canAdd(const Triple& v, uint32_t patch, bool sectors) const {
  if (byVerts_.count(sorted(v))) return false;
  const Vec3& p0 = pos_[size_t(v[0])];
  const Vec3& p1 = pos_[size_t(v[1])];
  const Vec3& p2 = pos_[size_t(v[2])];
  const double longest = std::max({norm(sub(p1, p0)), norm(sub(p2, p1)), norm(sub(p0, p2))});
  if (norm(cross(sub(p1, p0), sub(p2, p0))) <= 1e-9 * longest * longest) return false;
  for (int e = 0; e < 3; ++e) {
    const int32_t a = v[size_t(e)], b = v[size_t((e + 1) % 3)];
    auto it = edges_.find({edgeKey(a, b), patch});
    if (it == edges_.end()) continue;
    const EdgeRec& r = it->second;
    if (r.count >= (isRim(a, b, patch) ? 1 : 2)) return false;
    if (r.count == 1 && direction(tris_[size_t(r.t[0])].v, a, b) != -1) return false;
  }
  for (int c = 0; c < 3; ++c) {
    const int32_t u = v[size_t(c)];
    const int s = slotOf(u, patch);
    if (s < 0) return false;
    if (!sectors) continue;
    const Frame& f = frame_[size_t(s)];
    double a0, w0;
    if (!sector(u, v[size_t((c + 1) % 3)], v[size_t((c + 2) % 3)], f, a0, w0)) return false;
    for (int32_t t : fan_[size_t(s)]) {
      const Triple& o = tris_[size_t(t)].v;
      const int k = o[0] == u ? 0 : (o[1] == u ? 1 : 2);
      double a1, w1;
      sector(u, o[size_t((k + 1) % 3)], o[size_t((k + 2) % 3)], f, a1, w1);
      const double d = wrapAngle(a1 - a0);
      if (d < w0 - 1e-9 || d + w1 > kTwoPi + 1e-9) return false;
    }
  }
  return true;
}

int32_t Builder::addTri(const Triple& v, uint32_t patch, Source src) {
  const int32_t id = int32_t(tris_.size());
  tris_.push_back({v, patch, src, true});
  for (int e = 0; e < 3; ++e) {
    EdgeRec& r = edges_[{edgeKey(v[size_t(e)], v[size_t((e + 1) % 3)]), patch}];
    if (r.count < 2) r.t[r.count] = id;
    ++r.count;
  }
  byVerts_[sorted(v)] = id;
  for (int32_t u : v) fan_[size_t(slotOf(u, patch))].push_back(id);
  return id;
}

void Builder::removeTri(int32_t id) {
  Tri& t = tris_[size_t(id)];
  if (!t.alive) return;
  t.alive = false;
  for (int e = 0; e < 3; ++e) {
    auto it = edges_.find({edgeKey(t.v[size_t(e)], t.v[size_t((e + 1) % 3)]), t.patch});
    EdgeRec& r = it->second;
    if (r.t[0] == id) r.t[0] = r.t[1];
    r.t[1] = -1;
    if (--r.count == 0) edges_.erase(it);
  }
  byVerts_.erase(sorted(t.v));
  for (int32_t u : t.v) {
    auto& f = fan_[size_t(slotOf(u, t.patch))];
    f.erase(std::remove(f.begin(), f.end(), id), f.end());
  }
}

void Builder::select(std::vector<Candidate>& cands) {
  std::sort(cands.begin(), cands.end(), [](const Candidate& a, const Candidate& b) {
    if (a.votes != b.votes) return a.votes > b.votes;
    if (a.restricted != b.restricted) return a.restricted;
    if (a.quality != b.quality) return a.quality > b.quality;
    return a.key < b.key;
  });
  std::vector<char> taken(cands.size(), 0);
  for (size_t c = 0; c < cands.size(); ++c) {
    if (cands[c].votes < prm_.minVotes) break;
    const Triple v = orient(cands[c].key.v, cands[c].key.patch);
    if (canAdd(v, cands[c].key.patch)) {
      addTri(v, cands[c].key.patch, kStar);
      taken[c] = 1;
    } else {
      ++res_.nonManifoldRemoved;
    }
  }
  ctx_.checkCancel();
  // Closing triangles: any candidate not taken that closes at least two open edges of its patch
  // (more than it opens), until nothing changes.
  for (int round = 0; round < 6; ++round) {
    bool changed = false;
    for (size_t c = 0; c < cands.size(); ++c) {
      if (taken[c]) continue;
      const uint32_t patch = cands[c].key.patch;
      const Triple& v = cands[c].key.v;
      int closes = 0, opens = 0;
      for (int e = 0; e < 3; ++e) {
        const int32_t a = v[size_t(e)], b = v[size_t((e + 1) % 3)];
        const int use = edgeCount(a, b, patch);
        if (isRim(a, b, patch))
          closes += use == 0;
        else if (use == 1)
          ++closes;
        else if (use == 0)
          ++opens;
      }
      if (closes < 2 || closes <= opens) continue;
      const Triple o = orient(v, patch);
      if (!canAdd(o, patch)) continue;
      addTri(o, patch, cands[c].votes >= prm_.minVotes ? kStar : kSingleVote);
      taken[c] = 1;
      changed = true;
    }
    if (!changed) break;
  }
}

}  // namespace ldt

}  // namespace femesher
