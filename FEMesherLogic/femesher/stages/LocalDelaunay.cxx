// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/RunContext.h>
#include <femesher/stages/internal/LocalDelaunayBuilder.h>

namespace femesher {

namespace ldt {

void Builder::collect(std::vector<Triple>& tris,
                      std::vector<std::pair<uint16_t, uint16_t>>& pairs) const {
  tris.clear();
  pairs.clear();
  for (const Tri& t : tris_) {
    if (!t.alive) continue;
    tris.push_back(t.v);
    pairs.push_back(patchPairs_[t.patch]);
  }
}

void Builder::run() {
  pos_.resize(n_);
  for (size_t i = 0; i < n_; ++i) pos_[i] = vol_.localToCanonical(P_[i].local);
  rdt_.delaunay->adjacency(n_, off_, adj_);
  buildPatches();
  mapRestricted();
  buildLines();
  ctx_.progress(0.1);
  std::vector<Candidate> cands = computeCandidates();
  ctx_.progress(0.5);
  edges_.reserve(cands.size() * 2);
  byVerts_.reserve(cands.size());
  select(cands);
  std::vector<Candidate>().swap(cands);
  std::vector<Triple> tris;
  std::vector<std::pair<uint16_t, uint16_t>> pairs;
  collect(tris, pairs);
  res_.openEdgesBefore = oddEdges(tris, pairs).size();
  res_.openEdgesAfterFill = res_.openEdgesBefore;
  ctx_.progress(0.6);
  if (prm_.fillLoops && res_.openEdgesBefore > 0) {
    fillHoles();
    collect(tris, pairs);
    res_.openEdgesAfterFill = oddEdges(tris, pairs).size();
  }
  ctx_.progress(0.7);
  if (prm_.restrictedClosure) restrictedClosure();
  ctx_.progress(0.95);
  // Deterministic output order: by patch, then by vertices.
  std::vector<size_t> order;
  for (size_t t = 0; t < tris_.size(); ++t)
    if (tris_[t].alive) order.push_back(t);
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    const auto &pa = patchPairs_[tris_[a].patch], &pb = patchPairs_[tris_[b].patch];
    if (pa != pb) return pa < pb;
    return sorted(tris_[a].v) < sorted(tris_[b].v);
  });
  for (size_t t : order) {
    res_.triangles.push_back(tris_[t].v);
    res_.trianglePairs.push_back(patchPairs_[tris_[t].patch]);
    switch (tris_[t].source) {
      case kStar:
        ++res_.fromStars;
        break;
      case kSingleVote:
        ++res_.fromSingleVote;
        break;
      case kLoopFill:
        ++res_.fromLoopFill;
        break;
      case kRestricted:
        ++res_.fromRestricted;
        break;
    }
  }
  res_.openEdgesAfter = oddEdges(res_.triangles, res_.trianglePairs).size();
  if (!prm_.restrictedClosure) {
    std::vector<char> all(res_.triangles.size(), 1);
    res_.selfIntersectionsAfter = intersectingPairs(res_.triangles, all, pos_).size();
  }
  ctx_.progress(1.0);
}

}  // namespace ldt

size_t countOpenEdges(const std::vector<std::array<int32_t, 3>>& triangles,
                      const std::vector<std::pair<uint16_t, uint16_t>>& pairs) {
  return ldt::oddEdges(triangles, pairs).size();
}

size_t countSelfIntersections(const std::vector<Vec3>& points,
                              const std::vector<std::array<int32_t, 3>>& triangles) {
  std::vector<char> all(triangles.size(), 1);
  return ldt::intersectingPairs(triangles, all, points).size();
}

LocalDelaunayResult buildLocalDelaunaySurface(const IndicatorField& field,
                                              const std::vector<Particle>& particles,
                                              const Junctions& junctions,
                                              const BoundarySurface& restricted,
                                              const LocalDelaunayParameters& params,
                                              RunContext& ctx) {
  LocalDelaunayResult res;
  if (!restricted.delaunay) return res;
  ldt::Builder(field, particles, junctions, restricted, ctx, params, res).run();
  return res;
}

}  // namespace femesher
