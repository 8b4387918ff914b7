// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/RunContext.h>
#include <femesher/Status.h>
#include <femesher/stages/LabelPreprocess.h>

#include <algorithm>
#include <map>
#include <sstream>
#include <unordered_map>

namespace femesher {

PreprocessedVolume preprocessLabels(const LabelVolume& in, const LabelPreprocessParameters& params,
                                    RunContext& ctx) {
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

  // Decide which labels are kept.
  std::vector<int32_t> kept, dropped;
  for (const auto& [label, count] : counts) {
    if (label == 0) continue;
    if (int64_t(count) < params.minVoxels) dropped.push_back(label);
    else kept.push_back(label);
  }
  if (kept.empty()) {
    std::ostringstream os;
    os << (in.sourcePath.empty() ? std::string("The label map") : "'" + in.sourcePath + "'");
    if (counts.size() == 1 && counts.count(0))
      os << " holds only background (0): there is nothing to mesh. Check that you picked the "
            "segmentation and not the image.";
    else
      os << " has no label with at least min_voxels = " << params.minVoxels
         << " voxels. Lower min_voxels (--set min_voxels=1) to mesh tiny labels.";
    throw Error(ErrorCode::EmptyLabelMap, os.str());
  }
  for (int32_t d : dropped) {
    std::ostringstream os;
    const Material* m = findMaterial(in.materials, d);
    os << "Label " << d;
    if (m && !m->name.empty()) os << " (" << m->name << ")";
    os << " has only " << counts[d] << " voxels (< min_voxels = " << params.minVoxels
       << "): dropped, its voxels join the neighbouring label.";
    ctx.warn(os.str());
  }

  PreprocessedVolume out;
  out.spacing = in.spacing;
  out.droppedLabels = dropped;
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
    mat.name = m && !m->name.empty() ? m->name : "label " + std::to_string(k);
    mat.color = m ? m->color : defaultLabelColor(k);
    out.materials.push_back(mat);
  }
  constexpr uint16_t kDropped = 0xFFFF;
  for (int32_t d : dropped) compact[d] = kDropped;

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
  for (int k = margin; k < out.dims[2] - margin; ++k)
    for (int j = margin; j < out.dims[1] - margin; ++j)
      for (int i = margin; i < out.dims[0] - margin; ++i) {
        const int32_t u = in.at(i + out.offset[0], j + out.offset[1], k + out.offset[2]);
        const uint16_t c = u == 0 ? 0 : compact.at(u);
        const size_t idx = out.index(i, j, k);
        out.labels[idx] = c;
        if (c == kDropped) droppedVoxels.push_back(idx);
      }
  ctx.progress(0.6);

  // Fill dropped voxels from their kept 6-neighbours (most common), layer by layer.
  const long sx = 1, sy = out.dims[0], sz = long(out.dims[0]) * out.dims[1];
  while (!droppedVoxels.empty()) {
    std::vector<std::pair<size_t, uint16_t>> assign;
    std::vector<size_t> still;
    for (size_t idx : droppedVoxels) {
      uint16_t cand[6];
      int nc = 0;
      for (long d : {sx, -sx, sy, -sy, sz, -sz}) {
        const uint16_t l = out.labels[size_t(long(idx) + d)];  // margin keeps us inside
        if (l != kDropped) cand[nc++] = l;
      }
      if (nc == 0) {
        still.push_back(idx);
        continue;
      }
      // Most common; ties -> prefer a material over background, then the smaller id.
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
    }
    if (assign.empty()) {  // isolated region of dropped labels with no kept neighbour: cannot be
      for (size_t idx : still) out.labels[idx] = 0;
      break;
    }
    for (const auto& [idx, l] : assign) out.labels[idx] = l;
    droppedVoxels.swap(still);
  }

  out.voxelCounts.assign(out.userLabel.size(), 0);
  for (uint16_t l : out.labels) ++out.voxelCounts[l];
  if (noBackground) out.materials[0].name = "outside";
  ctx.progress(1.0);
  return out;
}

}  // namespace femesher
