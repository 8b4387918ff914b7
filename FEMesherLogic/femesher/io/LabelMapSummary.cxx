// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/io/LabelMapSummary.h>
#include <femesher/io/LabelValidation.h>

#include <algorithm>
#include <limits>
#include <unordered_map>
#include <unordered_set>

namespace femesher {

namespace {

/// Label ranges up to this size get a flat label -> compact index table, larger ones a hash map.
constexpr int64_t kFlatRange = int64_t(1) << 24;

/// A run of equal labels along x in one row.
struct Run {
  int32_t begin, end;  ///< x range [begin, end)
  uint32_t label;      ///< compact label index
};

class UnionFind {
 public:
  uint32_t add() {
    parent_.push_back(uint32_t(parent_.size()));
    return parent_.back();
  }
  uint32_t find(uint32_t x) {
    while (parent_[x] != x) {
      parent_[x] = parent_[parent_[x]];
      x = parent_[x];
    }
    return x;
  }
  void unite(uint32_t a, uint32_t b) {
    a = find(a);
    b = find(b);
    if (a != b) parent_[std::max(a, b)] = std::min(a, b);
  }
  size_t size() const { return parent_.size(); }

 private:
  std::vector<uint32_t> parent_;
};

/// Set of unordered label pairs (compact indices): a bit matrix for few labels, else a hash set.
class PairSet {
 public:
  explicit PairSet(size_t labels) : k_(labels) {
    if (k_ <= 4096) bits_.assign(k_ * k_, false);
  }
  void insert(uint32_t a, uint32_t b) {
    if (a > b) std::swap(a, b);
    const uint64_t key = (uint64_t(a) << 32) | b;
    if (key == last_) return;
    last_ = key;
    if (!bits_.empty()) bits_[size_t(a) * k_ + b] = true;
    else hash_.insert(key);
  }
  std::vector<std::pair<uint32_t, uint32_t>> pairs() const {
    std::vector<std::pair<uint32_t, uint32_t>> out;
    if (!bits_.empty()) {
      for (size_t a = 0; a < k_; ++a)
        for (size_t b = a + 1; b < k_; ++b)
          if (bits_[a * k_ + b]) out.emplace_back(uint32_t(a), uint32_t(b));
    } else {
      for (uint64_t key : hash_) out.emplace_back(uint32_t(key >> 32), uint32_t(key & 0xffffffffu));
    }
    return out;
  }

 private:
  size_t k_;
  uint64_t last_ = ~uint64_t(0);
  std::vector<bool> bits_;
  std::unordered_set<uint64_t> hash_;
};

/// Unite overlapping runs of equal label in two rows; record touching pairs where labels differ.
void linkRows(const Run* a, size_t na, uint32_t baseA, const Run* b, size_t nb, uint32_t baseB,
              UnionFind& uf, PairSet& pairs) {
  size_t i = 0, j = 0;
  while (i < na && j < nb) {
    if (a[i].label == b[j].label) uf.unite(baseA + uint32_t(i), baseB + uint32_t(j));
    else pairs.insert(a[i].label, b[j].label);
    if (a[i].end < b[j].end) ++i;
    else if (b[j].end < a[i].end) ++j;
    else ++i, ++j;
  }
}

}  // namespace

LabelMapSummary summarizeLabelMap(const LabelVolume& v) {
  LabelMapSummary s;
  const auto& d = v.dims;
  const size_t n = v.voxelCount();
  if (n == 0 || v.labels.size() != n) return s;
  const double voxelVolume = v.spacing[0] * v.spacing[1] * v.spacing[2];
  const int32_t* L = v.labels.data();

  // Compact label indices (labels sorted ascending).
  const std::vector<int32_t> ids = distinctLabels(v.labels, std::numeric_limits<size_t>::max());
  const int64_t lo = ids.front();
  const bool flat = int64_t(ids.back()) - lo < kFlatRange;
  std::vector<uint32_t> flatIndex;
  std::unordered_map<int32_t, uint32_t> hashIndex;
  if (flat) {
    flatIndex.assign(size_t(int64_t(ids.back()) - lo + 1), 0);
    for (size_t c = 0; c < ids.size(); ++c) flatIndex[size_t(int64_t(ids[c]) - lo)] = uint32_t(c);
  } else {
    for (size_t c = 0; c < ids.size(); ++c) hashIndex[ids[c]] = uint32_t(c);
  }
  auto compact = [&](int32_t x) {
    return flat ? flatIndex[size_t(int64_t(x) - lo)] : hashIndex.at(x);
  };
  const size_t k = ids.size();
  std::vector<LabelStatistics> stats(k);
  for (size_t c = 0; c < k; ++c) {
    stats[c].id = ids[c];
    stats[c].bboxMin = {d[0], d[1], d[2]};
    stats[c].bboxMax = {-1, -1, -1};
  }

  // Row runs, components (union-find over runs) and touching pairs.
  const size_t rows = size_t(d[1]) * size_t(d[2]);
  std::vector<Run> runs;
  std::vector<size_t> rowStart(rows + 1, 0);
  UnionFind uf;
  PairSet pairs(k);
  for (int kz = 0; kz < d[2]; ++kz)
    for (int j = 0; j < d[1]; ++j) {
      const size_t row = size_t(j) + size_t(d[1]) * size_t(kz);
      rowStart[row] = runs.size();
      const int32_t* r = L + row * size_t(d[0]);
      int32_t i = 0;
      while (i < d[0]) {
        const int32_t x = r[i];
        int32_t e = i + 1;
        while (e < d[0] && r[e] == x) ++e;
        const uint32_t c = compact(x);
        if (!runs.empty() && runs.size() > rowStart[row]) pairs.insert(runs.back().label, c);
        runs.push_back({i, e, c});
        uf.add();
        LabelStatistics& st = stats[c];
        st.voxels += size_t(e - i);
        st.bboxMin = {std::min(st.bboxMin[0], int(i)), std::min(st.bboxMin[1], j), std::min(st.bboxMin[2], kz)};
        st.bboxMax = {std::max(st.bboxMax[0], int(e - 1)), std::max(st.bboxMax[1], j), std::max(st.bboxMax[2], kz)};
        i = e;
      }
      rowStart[row + 1] = runs.size();
      auto link = [&](size_t other) {
        linkRows(runs.data() + rowStart[row], rowStart[row + 1] - rowStart[row], uint32_t(rowStart[row]),
                 runs.data() + rowStart[other], rowStart[other + 1] - rowStart[other],
                 uint32_t(rowStart[other]), uf, pairs);
      };
      if (j > 0) link(row - 1);
      if (kz > 0) link(row - size_t(d[1]));
    }
  for (size_t r = 0; r < runs.size(); ++r)
    if (uf.find(uint32_t(r)) == r) ++stats[runs[r].label].components;
  std::vector<Run>().swap(runs);

  // 2x2x2 cells: count distinct labels, skipping uniform cells quickly.
  const size_t sy = size_t(d[0]), sz = size_t(d[0]) * size_t(d[1]);
  for (int kz = 0; kz + 1 < d[2]; ++kz)
    for (int j = 0; j + 1 < d[1]; ++j) {
      const int32_t* a = L + size_t(j) * sy + size_t(kz) * sz;
      const int32_t* b = a + sy;
      const int32_t* c = a + sz;
      const int32_t* e = c + sy;
      for (int i = 0; i + 1 < d[0]; ++i) {
        const int32_t x = a[i];
        if (((a[i + 1] ^ x) | (b[i] ^ x) | (b[i + 1] ^ x) | (c[i] ^ x) | (c[i + 1] ^ x) | (e[i] ^ x) |
             (e[i + 1] ^ x)) == 0)
          continue;
        const int32_t cell[8] = {x, a[i + 1], b[i], b[i + 1], c[i], c[i + 1], e[i], e[i + 1]};
        int distinct = 0;
        for (int q = 0; q < 8; ++q) {
          bool seen = false;
          for (int p = 0; p < q && !seen; ++p) seen = cell[p] == cell[q];
          distinct += !seen;
        }
        if (distinct >= 3) ++s.tripleCells;
        if (distinct >= 4) ++s.quadrupleCells;
      }
    }

  for (auto& st : stats) {
    st.volumeMm3 = double(st.voxels) * voxelVolume;
    const Material* m = findMaterial(v.materials, st.id);
    st.name = m ? m->name : (st.id == 0 ? "background" : "label " + std::to_string(st.id));
  }
  // Background first, then ascending ids.
  std::stable_partition(stats.begin(), stats.end(), [](const LabelStatistics& st) { return st.id == 0; });
  s.labels = std::move(stats);
  for (const auto& [a, b] : pairs.pairs()) s.touchingPairs.emplace_back(ids[a], ids[b]);
  std::sort(s.touchingPairs.begin(), s.touchingPairs.end());
  return s;
}

}  // namespace femesher
