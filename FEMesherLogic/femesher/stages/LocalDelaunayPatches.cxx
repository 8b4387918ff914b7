// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/Parallel.h>
#include <femesher/RunContext.h>
#include <femesher/stages/internal/LocalDelaunayBuilder.h>

#include <cstring>

namespace femesher {

namespace ldt {

uint32_t Builder::patchFor(uint16_t a, uint16_t b) {
  if (a > b) std::swap(a, b);
  auto it = patchId_.find({a, b});
  if (it != patchId_.end()) return it->second;
  const uint32_t id = uint32_t(patchPairs_.size());
  patchId_[{a, b}] = id;
  patchPairs_.emplace_back(a, b);
  return id;
}

Vec3 Builder::gradientMm(uint16_t m, int32_t i) const {
  const Vec3 g = field_.gradient(m, P_[size_t(i)].local);
  return {g[0] / vol_.spacing[0], g[1] / vol_.spacing[1], g[2] / vol_.spacing[2]};
}

Vec3 Builder::normalAt(const Vec3& local, uint32_t patch) const {
  const auto [a, b] = patchPairs_[patch];
  const Vec3 ga = field_.gradient(a, local), gb = field_.gradient(b, local);
  return normalized({(gb[0] - ga[0]) / vol_.spacing[0], (gb[1] - ga[1]) / vol_.spacing[1],
                     (gb[2] - ga[2]) / vol_.spacing[2]});
}

void Builder::buildPatches() {
  memOff_.assign(n_ + 1, 0);
  std::vector<std::vector<uint32_t>> mem(n_);
  for (size_t i = 0; i < n_; ++i) {
    if (P_[i].junction < 0) {
      mem[i].push_back(patchFor(P_[i].a, P_[i].b));
      continue;
    }
    const JunctionPoint& j = J_.particles[size_t(P_[i].junction)];
    for (int x = 0; x < j.count; ++x)
      for (int y = x + 1; y < j.count; ++y) mem[i].push_back(patchFor(j.labels[x], j.labels[y]));
  }
  for (size_t i = 0; i < n_; ++i) memOff_[i + 1] = memOff_[i] + uint32_t(mem[i].size());
  memPatch_.resize(memOff_[n_]);
  frame_.resize(memOff_[n_]);
  for (size_t i = 0; i < n_; ++i)
    std::copy(mem[i].begin(), mem[i].end(), memPatch_.begin() + memOff_[i]);
  // Normals: the gradient of f_b - f_a at the particle, averaged over the particle and its
  // Delaunay neighbours on the same patch (the gradient is noisy at the voxel scale on thin and
  // curved parts); a neighbour whose normal points the other way (the far sheet of a thin layer)
  // is left out.
  std::vector<Vec3> nrm(memPatch_.size()), next(memPatch_.size());
  parallelFor(n_, ctx_.threads(), [&](size_t b, size_t e, int) {
    for (size_t i = b; i < e; ++i)
      for (uint32_t s = memOff_[i]; s < memOff_[i + 1]; ++s)
        nrm[s] = normalAt(P_[i].local, memPatch_[s]);
  });
  for (int pass = 0; pass < prm_.normalSmoothing; ++pass) {
    parallelFor(n_, ctx_.threads(), [&](size_t b, size_t e, int) {
      for (size_t i = b; i < e; ++i)
        for (uint32_t s = memOff_[i]; s < memOff_[i + 1]; ++s) {
          Vec3 sum = nrm[s];
          for (uint32_t k = off_[i]; k < off_[i + 1]; ++k) {
            const int sq = slotOf(int32_t(adj_[k]), memPatch_[s]);
            if (sq >= 0 && dot(nrm[size_t(sq)], nrm[s]) > -0.5) sum = add(sum, nrm[size_t(sq)]);
          }
          next[s] = norm(sum) > 0 ? normalized(sum) : nrm[s];
        }
    });
    nrm.swap(next);
  }
  for (size_t s = 0; s < nrm.size(); ++s) frame_[s] = frameOf(nrm[s]);
  fan_.assign(memPatch_.size(), {});
}

void Builder::mapRestricted() {
  struct VecHash {
    size_t operator()(const Vec3& v) const {
      uint64_t h = 0xCBF29CE484222325ull;
      for (double x : v) {
        uint64_t b;
        std::memcpy(&b, &x, sizeof b);
        h = (h ^ b) * 0x100000001B3ull;
      }
      return size_t(h);
    }
  };
  std::unordered_map<Vec3, int32_t, VecHash> id;
  id.reserve(n_);
  for (size_t i = 0; i < n_; ++i) id.emplace(pos_[i], int32_t(i));
  std::vector<int32_t> map(rdt_.points.size(), -1);
  for (size_t k = 0; k < rdt_.points.size(); ++k) {
    auto it = id.find(rdt_.points[k]);
    if (it != id.end()) map[k] = it->second;
  }
  for (size_t t = 0; t < rdt_.triangles.size(); ++t) {
    Triple v;
    bool ok = true;
    for (int k = 0; k < 3; ++k) {
      v[size_t(k)] = map[size_t(rdt_.triangles[t][size_t(k)])];
      ok = ok && v[size_t(k)] >= 0;
    }
    if (!ok) {
      ++res_.unmappedRestricted;
      continue;
    }
    const uint32_t patch = patchFor(rdt_.trianglePairs[t].first, rdt_.trianglePairs[t].second);
    rtris_.push_back({v, patch});
    rset_.insert({sorted(v), patch});
  }
}

std::vector<uint32_t> Builder::triplesOf(int32_t i) {
  std::vector<uint32_t> out;
  if (P_[size_t(i)].junction < 0) return out;
  const JunctionPoint& j = J_.particles[size_t(P_[size_t(i)].junction)];
  for (int x = 0; x < j.count; ++x)
    for (int y = x + 1; y < j.count; ++y)
      for (int z = y + 1; z < j.count; ++z) {
        const std::array<uint16_t, 3> t{j.labels[x], j.labels[y], j.labels[z]};
        auto it = tripleId_.find(t);
        if (it == tripleId_.end()) {
          it = tripleId_.emplace(t, uint32_t(triples_.size())).first;
          triples_.push_back(t);
        }
        out.push_back(it->second);
      }
  return out;
}

void Builder::buildLines() {
  links_.assign(n_, {});
  std::vector<int32_t> junction;
  for (size_t i = 0; i < n_; ++i)
    if (P_[i].junction >= 0) junction.push_back(int32_t(i));
  std::unordered_map<int32_t, std::vector<uint32_t>> tri;
  std::unordered_map<int32_t, Vec3> tangent;  // triple particles: direction of the line
  for (int32_t i : junction) {
    tri[i] = triplesOf(i);
    const JunctionPoint& j = J_.particles[size_t(P_[size_t(i)].junction)];
    if (j.count == 3) {
      const Vec3 g0 = gradientMm(j.labels[0], i), g1 = gradientMm(j.labels[1], i),
                 g2 = gradientMm(j.labels[2], i);
      const Vec3 t = cross(sub(g0, g1), sub(g0, g2));
      const double l = norm(t), s = norm(sub(g0, g1)) * norm(sub(g0, g2));
      if (s > 0 && l > 0.1 * s) tangent[i] = scale(t, 1.0 / l);
    }
  }
  struct Cand {
    double len;
    int32_t i, j;
    uint32_t triple;
    bool operator<(const Cand& o) const {
      if (len != o.len) return len < o.len;
      if (i != o.i) return i < o.i;
      if (j != o.j) return j < o.j;
      return triple < o.triple;
    }
  };
  auto needs = [&](int32_t i) {
    return J_.particles[size_t(P_[size_t(i)].junction)].count == 4 ? 1 : 2;
  };
  auto linksIn = [&](int32_t i, uint32_t t) {
    int used = 0;
    for (const Link& l : links_[size_t(i)]) used += l.triple == t;
    return used;
  };
  // A particle takes at most two links per line, pointing apart; a triple particle with a defined
  // tangent links roughly along it.
  const double apart = prm_.lineTurn, along = prm_.lineAlongTangent;
  auto slotFree = [&](int32_t i, int32_t j, uint32_t t) {
    const Vec3 d = normalized(sub(pos_[size_t(j)], pos_[size_t(i)]));
    int used = 0;
    for (const Link& l : links_[size_t(i)]) {
      if (l.triple != t) continue;
      if (l.other == j) return false;
      ++used;
      const Vec3 e = normalized(sub(pos_[size_t(l.other)], pos_[size_t(i)]));
      if (dot(d, e) > apart) return false;
    }
    if (used >= 2) return false;
    auto tg = tangent.find(i);
    if (tg != tangent.end() && std::fabs(dot(d, tg->second)) < along) return false;
    return true;
  };
  std::vector<Cand> cands;
  std::vector<int32_t> near, ring;
  // Pass 1: Delaunay 2-ring pairs, shortest first. Pass 2: line ends to line ends within the
  // 3-ring (gaps left by the junction sampling).
  for (int pass = 0; pass < 2; ++pass) {
    cands.clear();
    for (int32_t i : junction) {
      if (pass == 1) {
        bool open = false;
        for (uint32_t t : tri[i]) open = open || linksIn(i, t) < needs(i);
        if (!open) continue;
      }
      near.assign(1, i);
      for (int hop = 0; hop < (pass == 0 ? 2 : 3); ++hop) {
        ring = near;
        for (int32_t q : ring)
          for (uint32_t k = off_[size_t(q)]; k < off_[size_t(q) + 1]; ++k)
            near.push_back(int32_t(adj_[k]));
        std::sort(near.begin(), near.end());
        near.erase(std::unique(near.begin(), near.end()), near.end());
      }
      for (int32_t j : near) {
        if (j <= i || P_[size_t(j)].junction < 0) continue;
        const double len = norm(sub(pos_[size_t(j)], pos_[size_t(i)]));
        for (uint32_t t : tri[i]) {
          if (std::find(tri[j].begin(), tri[j].end(), t) == tri[j].end()) continue;
          if (pass == 1 && (linksIn(i, t) >= needs(i) || linksIn(j, t) >= needs(j))) continue;
          cands.push_back({len, i, j, t});
        }
      }
    }
    std::sort(cands.begin(), cands.end());
    for (const Cand& c : cands) {
      if (pass == 1 &&
          (linksIn(c.i, c.triple) >= needs(c.i) || linksIn(c.j, c.triple) >= needs(c.j)))
        continue;
      if (!slotFree(c.i, c.j, c.triple) || !slotFree(c.j, c.i, c.triple)) continue;
      links_[size_t(c.i)].push_back({c.j, c.triple});
      links_[size_t(c.j)].push_back({c.i, c.triple});
      ++res_.lineLinks;
    }
  }
  for (int32_t i : junction)
    for (uint32_t t : tri[i]) {
      int used = 0;
      for (const Link& l : links_[size_t(i)]) used += l.triple == t;
      const bool quad = J_.particles[size_t(P_[size_t(i)].junction)].count == 4;
      if (used < (quad ? 1 : 2)) ++res_.lineEnds;
    }
}

bool Builder::farSideOfRim(int32_t x, int32_t y, int32_t z, uint32_t patch) const {
  for (const Link& l : links_[size_t(x)]) {
    if (l.other != y || !tripleHasPatch(l.triple, patch)) continue;
    const uint16_t c = thirdLabel(l.triple, patch);
    const Vec3 e = normalized(sub(pos_[size_t(y)], pos_[size_t(x)]));
    Vec3 d = sub(pos_[size_t(z)], scale(add(pos_[size_t(x)], pos_[size_t(y)]), 0.5));
    d = sub(d, scale(e, dot(d, e)));
    Vec3 g = add(gradientMm(c, x), gradientMm(c, y));
    g = sub(g, scale(e, dot(g, e)));
    if (dot(d, g) > 0) return true;
  }
  return false;
}

bool Builder::alongOneLine(const Triple& t, uint32_t patch) const {
  for (int32_t v : t)
    if (P_[size_t(v)].junction < 0) return false;
  const auto [pa, pb] = patchPairs_[patch];
  const JunctionPoint& ju = J_.particles[size_t(P_[size_t(t[0])].junction)];
  const JunctionPoint& jv = J_.particles[size_t(P_[size_t(t[1])].junction)];
  const JunctionPoint& jw = J_.particles[size_t(P_[size_t(t[2])].junction)];
  for (int k = 0; k < ju.count; ++k) {
    const uint16_t c = ju.labels[size_t(k)];
    if (c == pa || c == pb) continue;
    if (ju.contains(pa, pb) && jv.contains(pa, c) && jv.contains(pb, c) && jw.contains(pa, c) &&
        jw.contains(pb, c))
      return true;
  }
  return false;
}

}  // namespace ldt

}  // namespace femesher
