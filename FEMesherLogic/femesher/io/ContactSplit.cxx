// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/Status.h>
#include <femesher/UnionFind.h>
#include <femesher/io/ContactSplit.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <map>
#include <set>
#include <unordered_map>

namespace femesher {

namespace {

std::string trimmed(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r\n");
  if (b == std::string::npos) return {};
  return s.substr(b, s.find_last_not_of(" \t\r\n") - b + 1);
}

Error badPairs(const std::string& text, const std::string& why) {
  return Error(ErrorCode::InvalidArgument,
               "Parameter 'contact_pairs' = '" + text + "': " + why +
                   ". Give label pairs as A:B separated by commas, e.g. contact_pairs=2:4,6:5.");
}

bool parseLabel(const std::string& s, int32_t& out) {
  const std::string t = trimmed(s);
  if (t.empty()) return false;
  char* end = nullptr;
  errno = 0;
  const long v = std::strtol(t.c_str(), &end, 10);
  if (errno != 0 || *end != '\0' || v < INT32_MIN || v > INT32_MAX) return false;
  out = int32_t(v);
  return true;
}

struct FaceKeyHash {
  size_t operator()(const std::array<int32_t, 3>& k) const {
    uint64_t h = uint64_t(uint32_t(k[0]));
    h = h * 0x9E3779B97F4A7C15ull ^ uint64_t(uint32_t(k[1]));
    h = h * 0x9E3779B97F4A7C15ull ^ uint64_t(uint32_t(k[2]));
    return size_t(h ^ (h >> 29));
  }
};

std::array<int32_t, 3> faceKey(const std::array<int32_t, 4>& t, int opposite) {
  std::array<int32_t, 3> k{};
  for (int i = 0, n = 0; i < 4; ++i)
    if (i != opposite) k[size_t(n++)] = t[size_t(i)];
  std::sort(k.begin(), k.end());
  return k;
}

}  // namespace

std::vector<std::pair<int32_t, int32_t>> parseContactPairs(const std::string& text) {
  std::vector<std::pair<int32_t, int32_t>> pairs;
  if (trimmed(text).empty()) return pairs;
  std::set<std::pair<int32_t, int32_t>> seen;
  size_t start = 0;
  while (start <= text.size()) {
    size_t comma = text.find(',', start);
    if (comma == std::string::npos) comma = text.size();
    const std::string item = text.substr(start, comma - start);
    const auto colon = item.find(':');
    int32_t a = 0, b = 0;
    if (colon == std::string::npos || !parseLabel(item.substr(0, colon), a) ||
        !parseLabel(item.substr(colon + 1), b))
      throw badPairs(text, "'" + trimmed(item) + "' is not a pair of integer labels A:B");
    if (a == b) throw badPairs(text, "'" + trimmed(item) + "' pairs a label with itself");
    if (!seen.insert({std::min(a, b), std::max(a, b)}).second)
      throw badPairs(text, "the pair " + std::to_string(a) + ":" + std::to_string(b) +
                               " is given twice");
    pairs.emplace_back(a, b);
    start = comma + 1;
  }
  return pairs;
}

std::string contactPairsText(const std::vector<std::pair<int32_t, int32_t>>& pairs) {
  std::string s;
  for (const auto& [a, b] : pairs)
    s += (s.empty() ? "" : ",") + std::to_string(a) + ":" + std::to_string(b);
  return s;
}

Status checkContactPairs(const std::vector<std::pair<int32_t, int32_t>>& pairs,
                         const LabelVolume& input) {
  if (pairs.empty()) return Status::ok();
  const std::string source =
      input.sourcePath.empty() ? std::string("the label map") : "'" + input.sourcePath + "'";
  std::set<int32_t> present;
  for (size_t i = 0; i < input.labels.size(); ++i)
    if (i == 0 || input.labels[i] != input.labels[i - 1]) present.insert(input.labels[i]);
  if (!input.hasNoBackground()) present.erase(0);
  std::string presentText;
  for (int32_t l : present) presentText += (presentText.empty() ? "" : ", ") + std::to_string(l);
  std::map<std::pair<int32_t, int32_t>, bool> touching;
  for (const auto& [a, b] : pairs) {
    for (int32_t l : {a, b})
      if (!present.count(l))
        return {ErrorCode::InvalidArgument,
                "contact_pairs " + std::to_string(a) + ":" + std::to_string(b) + ": " + source +
                    " has no label " + std::to_string(l) + " (its materials are labels " +
                    presentText + "). Name two labels that touch (see `femesher info`), or drop "
                    "the pair."};
    touching[{std::min(a, b), std::max(a, b)}] = false;
  }
  // Face-adjacent voxels of each pair.
  const auto& d = input.dims;
  for (int k = 0; k < d[2]; ++k)
    for (int j = 0; j < d[1]; ++j)
      for (int i = 0; i < d[0]; ++i) {
        const int32_t l = input.at(i, j, k);
        const int32_t nbs[3] = {i + 1 < d[0] ? input.at(i + 1, j, k) : l,
                                j + 1 < d[1] ? input.at(i, j + 1, k) : l,
                                k + 1 < d[2] ? input.at(i, j, k + 1) : l};
        for (int32_t m : nbs)
          if (m != l) {
            auto it = touching.find({std::min(l, m), std::max(l, m)});
            if (it != touching.end()) it->second = true;
          }
      }
  for (const auto& [a, b] : pairs)
    if (!touching[{std::min(a, b), std::max(a, b)}])
      return {ErrorCode::InvalidArgument,
              "contact_pairs " + std::to_string(a) + ":" + std::to_string(b) + ": labels " +
                  std::to_string(a) + " and " + std::to_string(b) + " of " + source +
                  " do not touch (no voxel of one is next to a voxel of the other), so they "
                  "share no interface to split. Name two labels that touch, or drop the pair."};
  return Status::ok();
}

std::vector<ContactSurfacePair> splitContactInterfaces(
    TetMesh& mesh, const std::vector<std::pair<int32_t, int32_t>>& pairs) {
  std::vector<ContactSurfacePair> out;
  if (pairs.empty()) return out;
  const std::set<int32_t> present(mesh.tetLabels.begin(), mesh.tetLabels.end());
  std::string presentText;
  for (int32_t l : present) presentText += (presentText.empty() ? "" : ", ") + std::to_string(l);
  std::map<std::pair<int32_t, int32_t>, size_t> pairIndex;  // (min, max) -> index in `pairs`
  for (size_t p = 0; p < pairs.size(); ++p) {
    for (int32_t l : {pairs[p].first, pairs[p].second})
      if (!present.count(l))
        throw Error(ErrorCode::InvalidArgument,
                    "contact_pairs " + std::to_string(pairs[p].first) + ":" +
                        std::to_string(pairs[p].second) + ": label " + std::to_string(l) +
                        " is not in the mesh (its materials are " + presentText +
                        "); name two labels of the mesh that touch, or drop the pair.");
    pairIndex[{std::min(pairs[p].first, pairs[p].second),
               std::max(pairs[p].first, pairs[p].second)}] = p;
    out.push_back({pairs[p].first, pairs[p].second, {}, {}, 0});
  }
  const size_t nt = mesh.tets.size();
  // Neighbour across each face (tet*4 + opposite -> tet*4 + opposite of the other side, or -1).
  std::vector<int64_t> nb(4 * nt, -1);
  {
    std::unordered_map<std::array<int32_t, 3>, int64_t, FaceKeyHash> open;
    open.reserve(2 * nt + 16);
    for (size_t t = 0; t < nt; ++t)
      for (int k = 0; k < 4; ++k) {
        const int64_t id = int64_t(4 * t + size_t(k));
        auto [it, fresh] = open.emplace(faceKey(mesh.tets[t], k), id);
        if (!fresh) {
          nb[size_t(id)] = it->second;
          nb[size_t(it->second)] = id;
          open.erase(it);
        }
      }
  }
  // The faces to cut and, per pair, the nodes on them.
  std::vector<char> cut(4 * nt, 0);
  std::vector<std::vector<char>> onPair(pairs.size(), std::vector<char>(mesh.points.size(), 0));
  std::vector<char> onAny(mesh.points.size(), 0);
  for (size_t f = 0; f < 4 * nt; ++f) {
    const int64_t g = nb[f];
    if (g < 0 || int64_t(f) > g) continue;
    const int32_t la = mesh.tetLabels[f / 4], lb = mesh.tetLabels[size_t(g) / 4];
    auto it = pairIndex.find({std::min(la, lb), std::max(la, lb)});
    if (la == lb || it == pairIndex.end()) continue;
    cut[f] = cut[size_t(g)] = 1;
    ContactSurfacePair& cp = out[it->second];
    const size_t fa = la == cp.labelA ? f : size_t(g), fb = la == cp.labelA ? size_t(g) : f;
    cp.facesA.push_back({int32_t(fa / 4), int32_t(fa % 4)});
    cp.facesB.push_back({int32_t(fb / 4), int32_t(fb % 4)});
    for (int k = 0; k < 4; ++k)
      if (k != int(f % 4)) {
        const auto v = size_t(mesh.tets[f / 4][size_t(k)]);
        onPair[it->second][v] = onAny[v] = 1;
      }
  }
  for (const auto& cp : out)
    if (cp.facesA.empty())
      throw Error(ErrorCode::InvalidArgument,
                  "contact_pairs " + std::to_string(cp.labelA) + ":" + std::to_string(cp.labelB) +
                      ": labels " + std::to_string(cp.labelA) + " and " +
                      std::to_string(cp.labelB) +
                      " share no interface in the mesh, so there is nothing to split; name two "
                      "labels that touch, or drop the pair.");
  // Incident tets of the nodes on cut faces (CSR).
  const size_t np = mesh.points.size();
  std::vector<size_t> start(np + 1, 0);
  for (const auto& t : mesh.tets)
    for (int32_t v : t)
      if (onAny[size_t(v)]) ++start[size_t(v) + 1];
  for (size_t v = 0; v < np; ++v) start[v + 1] += start[v];
  std::vector<int32_t> incident(start[np]);
  {
    std::vector<size_t> fill(start.begin(), start.end() - 1);
    for (size_t t = 0; t < nt; ++t)
      for (int32_t v : mesh.tets[t])
        if (onAny[size_t(v)]) incident[fill[size_t(v)]++] = int32_t(t);
  }
  // Components around each node; copies for all but the first.
  struct Reassign {
    int32_t tet, local, vertex;
  };
  std::vector<Reassign> changes;
  for (size_t v = 0; v < np; ++v) {
    if (!onAny[v]) continue;
    const int32_t* T = incident.data() + start[v];  // ascending tet indices
    const size_t n = start[v + 1] - start[v];
    UnionFind components(n);
    auto localOf = [&](int32_t t) {
      return int(std::lower_bound(T, T + n, t) - T);
    };
    for (size_t i = 0; i < n; ++i) {
      const auto& tet = mesh.tets[size_t(T[i])];
      for (int k = 0; k < 4; ++k) {
        if (tet[size_t(k)] == int32_t(v)) continue;  // the face opposite k contains v
        const size_t f = 4 * size_t(T[i]) + size_t(k);
        if (nb[f] < 0 || cut[f]) continue;
        components.unite(int(i), localOf(int32_t(nb[f] / 4)));
      }
    }
    std::vector<int32_t> copyOf(n, -1);  // per component root: the vertex it gets
    int copies = 0;
    for (size_t i = 0; i < n; ++i) {
      const int r = components.find(int(i));
      if (copyOf[size_t(r)] < 0) {
        if (r == 0) {
          copyOf[0] = int32_t(v);
        } else {
          copyOf[size_t(r)] = int32_t(mesh.points.size());
          mesh.points.push_back(mesh.points[v]);
          ++copies;
        }
      }
      if (copyOf[size_t(r)] == int32_t(v)) continue;
      const auto& tet = mesh.tets[size_t(T[i])];
      const int local = int(std::find(tet.begin(), tet.end(), int32_t(v)) - tet.begin());
      changes.push_back({T[i], local, copyOf[size_t(r)]});
    }
    for (size_t p = 0; p < out.size(); ++p)
      if (onPair[p][v]) out[p].duplicatedNodes += size_t(copies);
  }
  for (const auto& c : changes) mesh.tets[size_t(c.tet)][size_t(c.local)] = c.vertex;
  return out;
}

std::vector<NamedNodeSet> boxFaceNodeSets(const TetMesh& mesh, const LabelVolume& geometry,
                                          double toleranceVoxels) {
  static const char* names[3][2] = {{"BOX_XMIN", "BOX_XMAX"},
                                    {"BOX_YMIN", "BOX_YMAX"},
                                    {"BOX_ZMIN", "BOX_ZMAX"}};
  std::vector<NamedNodeSet> sets(6);
  for (size_t i = 0; i < mesh.points.size(); ++i) {
    const Vec3 idx = geometry.physicalToIndex(mesh.points[i]);
    for (int a = 0; a < 3; ++a) {
      if (std::fabs(idx[a] + 0.5) <= toleranceVoxels) sets[size_t(2 * a)].nodes.push_back(int32_t(i));
      if (std::fabs(idx[a] - (geometry.dims[a] - 0.5)) <= toleranceVoxels)
        sets[size_t(2 * a + 1)].nodes.push_back(int32_t(i));
    }
  }
  std::vector<NamedNodeSet> out;
  for (int s = 0; s < 6; ++s)
    if (!sets[size_t(s)].nodes.empty()) {
      sets[size_t(s)].name = names[s / 2][s % 2];
      out.push_back(std::move(sets[size_t(s)]));
    }
  return out;
}

}  // namespace femesher
