// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/RunContext.h>
#include <femesher/Status.h>
#include <femesher/stages/LabelPreprocess.h>

#include <algorithm>
#include <map>
#include <set>
#include <sstream>
#include <unordered_map>

namespace femesher {

namespace {

/// The user's name of `label`, else the label map's, else "".
std::string givenName(const LabelVolume& in, const LabelPreprocessParameters& params, int32_t label) {
  if (auto it = params.names.find(label); it != params.names.end() && !it->second.empty())
    return it->second;
  const Material* m = findMaterial(in.materials, label);
  return m ? m->name : std::string();
}

std::string labelName(const LabelVolume& in, const LabelPreprocessParameters& params, int32_t label) {
  std::ostringstream os;
  os << "Label " << label;
  const std::string name = givenName(in, params, label);
  if (!name.empty()) os << " (" << name << ")";
  return os.str();
}

/// Names the exclusions that empty the label or that name a label the map does not have.
void warnAboutExclusions(const LabelVolume& input, const LabelPreprocessParameters& params,
                         const std::set<int32_t>& present, RunContext& ctx) {
  for (const auto& [label, how] : params.excluded) {
    if (!present.count(label)) {
      ctx.warn("Label " + std::to_string(label) +
               " is excluded, but the label map has no such label: nothing to exclude.");
    } else if (how == Exclusion::Background) {
      ctx.warn(labelName(input, params, label) +
               " is excluded: its voxels are background (the mesh has a cavity or a cut there).");
    }
  }
}

/// Fills the voxels marked `dropped` from their kept 6-neighbours (the most common; ties prefer a
/// material over background, then the smaller id), layer by layer. Voxels of a label in
/// `materialsOnly` (merged exclusions) take materials only, never background, unless no material
/// can reach them. Returns, per user label of the dropped voxels, how many voxels each compact
/// label received.
std::map<int32_t, std::map<uint16_t, size_t>> fillFromNeighbours(
    PreprocessedVolume& out, uint16_t dropped, std::vector<size_t> voxels,
    std::vector<int32_t> from, const std::set<int32_t>& materialsOnly) {
  std::map<int32_t, std::map<uint16_t, size_t>> received;
  const long sx = 1, sy = out.dims[0], sz = long(out.dims[0]) * out.dims[1];
  while (!voxels.empty()) {
    std::vector<std::pair<size_t, uint16_t>> assign;
    std::vector<int32_t> assignFrom, stillFrom;
    std::vector<size_t> still;
    for (size_t v = 0; v < voxels.size(); ++v) {
      const size_t idx = voxels[v];
      uint16_t cand[6];
      int nc = 0;
      const bool noBackground = materialsOnly.count(from[v]) > 0;
      for (long d : {sx, -sx, sy, -sy, sz, -sz}) {
        const uint16_t l = out.labels[size_t(long(idx) + d)];  // margin keeps us inside
        if (l != dropped && !(noBackground && l == 0)) cand[nc++] = l;
      }
      if (nc == 0) {
        still.push_back(idx);
        stillFrom.push_back(from[v]);
        continue;
      }
      uint16_t best = cand[0];
      int bestCount = 0;
      for (int a = 0; a < nc; ++a) {
        int c = 0;
        for (int b = 0; b < nc; ++b) c += cand[a] == cand[b];
        if (c > bestCount || (c == bestCount && ((best == 0 && cand[a] != 0) ||
                                                 (cand[a] != 0 && cand[a] < best)))) {
          best = cand[a];
          bestCount = c;
        }
      }
      assign.emplace_back(idx, best);
      assignFrom.push_back(from[v]);
    }
    if (assign.empty()) {  // an isolated region of dropped labels with no kept neighbour
      for (size_t v = 0; v < still.size(); ++v) {
        out.labels[still[v]] = 0;
        ++received[stillFrom[v]][0];
      }
      break;
    }
    for (size_t v = 0; v < assign.size(); ++v) {
      out.labels[assign[v].first] = assign[v].second;
      ++received[assignFrom[v]][assign[v].second];
    }
    voxels.swap(still);
    from.swap(stillFrom);
  }
  return received;
}

/// Says where the voxels of a material excluded with MergeIntoNeighbour went.
void warnMerged(const LabelVolume& input, const LabelPreprocessParameters& params,
                const PreprocessedVolume& out, int32_t label,
                const std::map<int32_t, std::map<uint16_t, size_t>>& received, RunContext& ctx) {
  std::ostringstream os;
  os << labelName(input, params, label) << " is excluded and merged into its neighbours:";
  auto it = received.find(label);
  if (it == received.end()) return;
  std::vector<std::pair<size_t, uint16_t>> byCount;
  for (const auto& [m, count] : it->second) byCount.emplace_back(count, m);
  std::sort(byCount.begin(), byCount.end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first > b.first : a.second < b.second;
  });
  const char* sep = " ";
  for (const auto& [count, m] : byCount) {
    os << sep << (m == 0 ? std::string("background") : out.materials[m].name + " (label " +
                                                            std::to_string(out.userLabel[m]) + ")")
       << " " << count << " voxels";
    sep = ", ";
  }
  os << ".";
  ctx.warn(os.str());
}

}  // namespace

PreprocessedVolume preprocessLabels(const LabelVolume& input,
                                    const LabelPreprocessParameters& params, RunContext& ctx) {
  // Materials excluded as background are background from here on (a copy only when there are).
  LabelVolume masked;
  const bool maskAny = std::any_of(params.excluded.begin(), params.excluded.end(), [](const auto& e) {
    return e.second == Exclusion::Background;
  });
  std::set<int32_t> present;  // user labels of the input (before masking)
  if (maskAny) {
    masked = input;
    for (int32_t& l : masked.labels) {
      auto it = params.excluded.find(l);
      if (it != params.excluded.end() && it->second == Exclusion::Background) {
        present.insert(l);
        l = 0;
      }
    }
  }
  const LabelVolume& in = maskAny ? masked : input;
  const size_t n = in.voxelCount();
  if (n == 0 || in.labels.size() != n)
    throw Error(ErrorCode::InvalidArgument, "The label map has no voxels.");
  const bool noBackground = in.hasNoBackground();

  // Count labels.
  std::map<int32_t, size_t> counts;
  {
    int32_t last = in.labels[0];
    size_t run = 0;
    for (size_t i = 0; i < n; ++i) {
      if (in.labels[i] == last) {
        ++run;
      } else {
        counts[last] += run;
        last = in.labels[i];
        run = 1;
      }
    }
    counts[last] += run;
  }
  ctx.progress(0.2);

  // Decide which labels are kept; merged exclusions are filled like dropped labels.
  std::vector<int32_t> kept, dropped, merged;
  for (const auto& [label, count] : counts) {
    if (label == 0) continue;
    if (params.excluded.count(label)) merged.push_back(label);
    else if (int64_t(count) < params.minVoxels) dropped.push_back(label);
    else kept.push_back(label);
  }
  for (const auto& c : counts) present.insert(c.first);
  warnAboutExclusions(input, params, present, ctx);
  if (kept.empty()) {
    std::ostringstream os;
    os << (in.sourcePath.empty() ? std::string("The label map") : "'" + in.sourcePath + "'");
    const bool anyExcluded = std::any_of(params.excluded.begin(), params.excluded.end(),
                                         [&](const auto& e) { return present.count(e.first) > 0; });
    if (anyExcluded && dropped.empty())
      os << " has no material left to mesh: every label is excluded. Include at least one.";
    else if (counts.size() == 1 && counts.count(0) && params.excluded.empty())
      os << " holds only background (0): there is nothing to mesh. Check that you picked the "
            "segmentation and not the image.";
    else
      os << " has no label with at least min_voxels = " << params.minVoxels
         << " voxels. Lower min_voxels (--set min_voxels=1) to mesh tiny labels.";
    throw Error(ErrorCode::EmptyLabelMap, os.str());
  }
  for (int32_t d : dropped) {
    std::ostringstream os;
    os << labelName(in, params, d) << " has only " << counts[d] << " voxels (< min_voxels = " << params.minVoxels
       << "): dropped, its voxels join the neighbouring label.";
    ctx.warn(os.str());
  }

  PreprocessedVolume out;
  out.spacing = in.spacing;
  out.droppedLabels = dropped;
  for (const auto& e : params.excluded)
    if (present.count(e.first)) out.excludedLabels.push_back(e.first);
  out.userLabel.push_back(0);
  Material bg;
  bg.id = 0;
  bg.name = "background";
  out.materials.push_back(bg);
  // user label -> compact id; dropped labels -> 0xFFFF (to be filled)
  std::unordered_map<int32_t, uint16_t> compact;
  compact[0] = 0;
  for (int32_t k : kept) {
    compact[k] = uint16_t(out.userLabel.size());
    out.userLabel.push_back(k);
    const Material* m = findMaterial(in.materials, k);
    Material mat;
    mat.id = k;
    const std::string name = givenName(in, params, k);
    mat.name = !name.empty() ? name : "label " + std::to_string(k);
    mat.color = m ? m->color : defaultLabelColor(k);
    out.materials.push_back(mat);
  }
  constexpr uint16_t kDropped = 0xFFFF;
  for (int32_t d : dropped) compact[d] = kDropped;
  for (int32_t d : merged) compact[d] = kDropped;

  // Bounding box of the labelled voxels (all voxels when there is no background).
  std::array<int, 3> lo{{in.dims[0], in.dims[1], in.dims[2]}}, hi{{-1, -1, -1}};
  for (int k = 0; k < in.dims[2]; ++k) {
    for (int j = 0; j < in.dims[1]; ++j) {
      const int32_t* row = &in.labels[in.index(0, j, k)];
      int first = -1, last = -1;
      for (int i = 0; i < in.dims[0]; ++i)
        if (row[i] != 0) {
          if (first < 0) first = i;
          last = i;
        }
      if (first < 0) continue;
      lo[0] = std::min(lo[0], first);
      hi[0] = std::max(hi[0], last);
      lo[1] = std::min(lo[1], j);
      hi[1] = std::max(hi[1], j);
      lo[2] = std::min(lo[2], k);
      hi[2] = std::max(hi[2], k);
    }
  }
  const int margin = std::max(2, params.margin);
  for (int a = 0; a < 3; ++a) {
    out.offset[a] = lo[a] - margin;
    out.inputDims[a] = in.dims[a];
    out.dims[a] = hi[a] - lo[a] + 1 + 2 * margin;
  }
  out.labels.assign(size_t(out.dims[0]) * out.dims[1] * out.dims[2], 0);
  std::vector<size_t> droppedVoxels;
  std::vector<int32_t> droppedFrom;  // user label of each dropped voxel (to name where it went)
  for (int k = margin; k < out.dims[2] - margin; ++k)
    for (int j = margin; j < out.dims[1] - margin; ++j)
      for (int i = margin; i < out.dims[0] - margin; ++i) {
        const int32_t u = in.at(i + out.offset[0], j + out.offset[1], k + out.offset[2]);
        const uint16_t c = u == 0 ? 0 : compact.at(u);
        const size_t idx = out.index(i, j, k);
        out.labels[idx] = c;
        if (c == kDropped) {
          droppedVoxels.push_back(idx);
          droppedFrom.push_back(u);
        }
      }
  ctx.progress(0.6);

  const auto received = fillFromNeighbours(out, kDropped, droppedVoxels, droppedFrom,
                                           std::set<int32_t>(merged.begin(), merged.end()));
  for (int32_t m : merged) warnMerged(input, params, out, m, received, ctx);

  out.voxelCounts.assign(out.userLabel.size(), 0);
  for (uint16_t l : out.labels) ++out.voxelCounts[l];
  if (noBackground) out.materials[0].name = "outside";
  ctx.progress(1.0);
  return out;
}

}  // namespace femesher
