// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file UnionFind.h
/// Disjoint sets over 0..n-1 with path halving; the smaller id becomes the root of a union, so a
/// component's representative is its smallest member (deterministic, independent of the order of
/// the unions).

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <numeric>
#include <vector>

namespace femesher {

struct UnionFind {
  std::vector<int32_t> parent;
  explicit UnionFind(size_t n) : parent(n) { std::iota(parent.begin(), parent.end(), 0); }
  int32_t find(int32_t x) {
    while (parent[size_t(x)] != x) x = parent[size_t(x)] = parent[size_t(parent[size_t(x)])];
    return x;
  }
  void unite(int32_t a, int32_t b) {
    a = find(a);
    b = find(b);
    if (a != b) parent[size_t(std::max(a, b))] = std::min(a, b);
  }
};

}  // namespace femesher
