// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/io/AtomicFile.h>
#include <femesher/io/LabelMapIO.h>

#include <itkImage.h>
#include <itkImageFileWriter.h>
#include <itkImageIOBase.h>
#include <itkImageIOFactory.h>
#include <itkMetaDataObject.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <numeric>
#include <set>
#include <sstream>
#include <unordered_map>
#include <unordered_set>

namespace femesher {

namespace fs = std::filesystem;

namespace {

std::string trim(const std::string& s) {
  const auto a = s.find_first_not_of(" \t\r\n");
  if (a == std::string::npos) return {};
  const auto b = s.find_last_not_of(" \t\r\n");
  return s.substr(a, b - a + 1);
}

/// Header lines (key -> value) of a text header ending at the first empty line (NRRD) or the
/// whole file (MetaImage .mhd: "Key = Value").
std::map<std::string, std::string> readTextHeader(const std::string& path, char sep,
                                                  size_t maxBytes = 1 << 20) {
  std::map<std::string, std::string> h;
  std::ifstream in(path, std::ios::binary);
  std::string line;
  size_t read = 0;
  while (std::getline(in, line) && read < maxBytes) {
    read += line.size() + 1;
    if (trim(line).empty()) break;
    if (!line.empty() && line[0] == '#') continue;
    const auto pos = line.find(sep);
    if (pos == std::string::npos) continue;
    // NRRD key/value pairs use ":=", fields use ": ".
    std::string key = trim(line.substr(0, pos));
    std::string value = line.substr(pos + 1);
    if (!value.empty() && value[0] == '=') value = value.substr(1);
    h[key] = trim(value);
  }
  return h;
}

Status corrupt(const std::string& path, const std::string& what) {
  return {ErrorCode::CorruptFile,
          "'" + path + "' is damaged: " + what +
              ". Re-export the file from the tool that made it (or use an uncompressed copy)."};
}

/// A MetaImage header that lies about its data: ITK would zero-fill silently.
Status checkMetaImage(const std::string& path) {
  const auto h = readTextHeader(path, '=');
  const auto dataIt = h.find("ElementDataFile");
  if (dataIt == h.end()) return Status::ok();
  std::string dataFile = dataIt->second;
  const auto compressed = h.find("CompressedData");
  const bool isCompressed = compressed != h.end() && (compressed->second == "True" || compressed->second == "true");
  uintmax_t available = 0;
  std::error_code ec;
  if (dataFile == "LOCAL") {
    // data follows the header; ITK checks sizes itself for raw data
    return Status::ok();
  }
  if (dataFile.find('%') != std::string::npos || dataFile == "LIST") return Status::ok();
  const fs::path dataPath = fs::path(path).parent_path() / dataFile;
  available = fs::file_size(dataPath, ec);
  if (ec)
    return {ErrorCode::CorruptFile, "'" + path + "' names the data file '" + dataPath.string() +
                                        "', which cannot be read. Keep the .mhd and its data file together."};
  if (isCompressed) {
    const auto cs = h.find("CompressedDataSize");
    if (cs != h.end()) {
      const uintmax_t declared = std::stoull(cs->second);
      if (declared != available)
        return corrupt(path, "its header says CompressedDataSize = " + cs->second + " but '" +
                                 dataPath.filename().string() + "' holds " + std::to_string(available) +
                                 " bytes, so a reader would silently zero-fill the missing voxels");
    }
    return Status::ok();
  }
  // Raw data: compare with the expected byte count.
  std::istringstream dims(h.count("DimSize") ? h.at("DimSize") : "");
  uintmax_t count = 1, d = 0;
  while (dims >> d) count *= d;
  static const std::map<std::string, int> bytes = {
      {"MET_UCHAR", 1}, {"MET_CHAR", 1}, {"MET_USHORT", 2}, {"MET_SHORT", 2}, {"MET_UINT", 4},
      {"MET_INT", 4},   {"MET_FLOAT", 4}, {"MET_ULONG", 8}, {"MET_LONG", 8}, {"MET_DOUBLE", 8},
      {"MET_ULONG_LONG", 8}, {"MET_LONG_LONG", 8}};
  const auto et = h.find("ElementType");
  if (et != h.end() && bytes.count(et->second)) {
    int channels = 1;
    if (h.count("ElementNumberOfChannels")) channels = std::stoi(h.at("ElementNumberOfChannels"));
    const uintmax_t expected = count * uintmax_t(bytes.at(et->second)) * uintmax_t(channels);
    if (available < expected)
      return corrupt(path, "the data file holds " + std::to_string(available) + " bytes but the header needs " +
                               std::to_string(expected));
  }
  return Status::ok();
}

struct SegmentInfo {
  std::string id, name;
  std::array<double, 3> color{{0.5, 0.5, 0.5}};
  int32_t labelValue = 1;
  int layer = 0;
};

std::vector<SegmentInfo> parseSegments(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::string line;
  std::map<int, SegmentInfo> segs;
  while (std::getline(in, line)) {
    if (trim(line).empty()) break;
    if (line.rfind("Segment", 0) != 0) continue;
    const auto sep = line.find(":=");
    if (sep == std::string::npos) continue;
    const std::string key = line.substr(0, sep), value = trim(line.substr(sep + 2));
    const auto us = key.find('_');
    if (us == std::string::npos) continue;
    int n = 0;
    try {
      n = std::stoi(key.substr(7, us - 7));
    } catch (...) {
      continue;
    }
    const std::string field = key.substr(us + 1);
    SegmentInfo& s = segs[n];
    if (field == "ID") s.id = value;
    else if (field == "Name") s.name = value;
    else if (field == "LabelValue") s.labelValue = std::atoi(value.c_str());
    else if (field == "Layer") s.layer = std::atoi(value.c_str());
    else if (field == "Color") {
      std::istringstream c(value);
      c >> s.color[0] >> s.color[1] >> s.color[2];
    }
  }
  std::vector<SegmentInfo> out;
  for (auto& [n, s] : segs) out.push_back(s);
  return out;
}

template <class T>
bool convertBuffer(const void* data, size_t n, std::vector<int32_t>& out, bool& nonInteger,
                   bool& outOfRange) {
  const T* p = static_cast<const T*>(data);
  out.resize(n);
  for (size_t i = 0; i < n; ++i) {
    const T v = p[i];
    if constexpr (std::is_floating_point_v<T>) {
      if (!std::isfinite(v) || v != std::floor(v)) {
        nonInteger = true;
        return false;
      }
    }
    if (double(v) > double(std::numeric_limits<int32_t>::max()) ||
        double(v) < double(std::numeric_limits<int32_t>::min())) {
      outOfRange = true;
      return false;
    }
    out[i] = int32_t(v);
  }
  return true;
}

}  // namespace

Result<LabelVolume> readLabelMap(const std::string& path) {
  std::error_code ec;
  if (!fs::exists(path, ec))
    return Result<LabelVolume>(ErrorCode::FileNotFound,
                               "'" + path + "' does not exist. Check the path and file name.");
  if (fs::is_directory(path, ec))
    return Result<LabelVolume>(ErrorCode::UnreadableFile,
                               "'" + path + "' is a folder; give a label map file (.nrrd, .nii.gz, .mha, "
                               ".seg.nrrd). DICOM folders: convert to NRRD/NIfTI first.");
  const std::string ext = fileExtension(path);
  if (ext == ".mhd") {
    if (Status s = checkMetaImage(path); !s) return s;
  }
  itk::ImageIOBase::Pointer io =
      itk::ImageIOFactory::CreateImageIO(path.c_str(), itk::ImageIOFactory::IOFileModeEnum::ReadMode);
  if (!io)
    return Result<LabelVolume>(ErrorCode::UnreadableFile,
                               "'" + path + "' is not an image FEMesher can read (supported: .nrrd, "
                               ".nhdr, .nii, .nii.gz, .mha, .mhd, .seg.nrrd).");
  io->SetFileName(path);
  try {
    io->ReadImageInformation();
  } catch (const itk::ExceptionObject& e) {
    return Result<LabelVolume>(ErrorCode::UnreadableFile,
                               "'" + path + "' cannot be read: " + std::string(e.GetDescription()));
  }
  const bool isSeg = ext == ".seg.nrrd";
  const unsigned dim = io->GetNumberOfDimensions();
  const unsigned comps = io->GetNumberOfComponents();
  // A .seg.nrrd with several layers is 4-D (layer axis first) or has several components.
  unsigned layers = 1;
  unsigned spatial0 = 0;
  if (isSeg && dim == 4) {
    layers = unsigned(io->GetDimensions(0));
    spatial0 = 1;
  } else if (dim != 3) {
    return Result<LabelVolume>(ErrorCode::NotALabelMap,
                               "'" + path + "' is a " + std::to_string(dim) +
                                   "-D image; FEMesher needs a 3-D label map.");
  }
  if (comps > 1 && !isSeg)
    return Result<LabelVolume>(ErrorCode::NotALabelMap,
                               "'" + path + "' has " + std::to_string(comps) +
                                   " values per voxel (a vector or colour image); FEMesher needs one "
                                   "integer label per voxel.");
  if (isSeg && comps > 1) layers = comps;

  LabelVolume v;
  v.sourcePath = path;
  for (unsigned a = 0; a < 3; ++a) {
    v.dims[a] = int(io->GetDimensions(a + spatial0));
    v.spacing[a] = io->GetSpacing(a + spatial0);
    v.origin[a] = io->GetOrigin(a + spatial0);
    const auto dir = io->GetDirection(a + spatial0);
    for (unsigned r = 0; r < 3; ++r) v.direction[3 * r + a] = dir[r + spatial0];
    if (!(v.spacing[a] > 0))
      return Result<LabelVolume>(ErrorCode::CorruptFile,
                                 "'" + path + "' has a non-positive voxel spacing.");
  }
  const size_t n = v.voxelCount();
  const size_t total = n * layers;
  if (n == 0)
    return Result<LabelVolume>(ErrorCode::EmptyLabelMap, "'" + path + "' has no voxels.");
  std::vector<char> buffer;
  try {
    buffer.resize(io->GetImageSizeInBytes());
    itk::ImageIORegion region(dim);
    for (unsigned a = 0; a < dim; ++a) {
      region.SetIndex(a, 0);
      region.SetSize(a, io->GetDimensions(a));
    }
    io->SetIORegion(region);
    io->Read(buffer.data());
  } catch (const itk::ExceptionObject& e) {
    return corrupt(path, "reading its voxel data failed (" + std::string(e.GetDescription()) +
                             "); the file is probably truncated");
  } catch (const std::bad_alloc&) {
    return Result<LabelVolume>(ErrorCode::UnreadableFile,
                               "'" + path + "' is too large to load into memory.");
  }
  std::vector<int32_t> values;
  bool nonInteger = false, outOfRange = false, ok = false;
  using CT = itk::IOComponentEnum;
  switch (io->GetComponentType()) {
    case CT::UCHAR: ok = convertBuffer<uint8_t>(buffer.data(), total, values, nonInteger, outOfRange); break;
    case CT::CHAR: ok = convertBuffer<int8_t>(buffer.data(), total, values, nonInteger, outOfRange); break;
    case CT::USHORT: ok = convertBuffer<uint16_t>(buffer.data(), total, values, nonInteger, outOfRange); break;
    case CT::SHORT: ok = convertBuffer<int16_t>(buffer.data(), total, values, nonInteger, outOfRange); break;
    case CT::UINT: ok = convertBuffer<uint32_t>(buffer.data(), total, values, nonInteger, outOfRange); break;
    case CT::INT: ok = convertBuffer<int32_t>(buffer.data(), total, values, nonInteger, outOfRange); break;
    case CT::ULONG: ok = convertBuffer<unsigned long>(buffer.data(), total, values, nonInteger, outOfRange); break;
    case CT::LONG: ok = convertBuffer<long>(buffer.data(), total, values, nonInteger, outOfRange); break;
    case CT::ULONGLONG: ok = convertBuffer<unsigned long long>(buffer.data(), total, values, nonInteger, outOfRange); break;
    case CT::LONGLONG: ok = convertBuffer<long long>(buffer.data(), total, values, nonInteger, outOfRange); break;
    case CT::FLOAT: ok = convertBuffer<float>(buffer.data(), total, values, nonInteger, outOfRange); break;
    case CT::DOUBLE: ok = convertBuffer<double>(buffer.data(), total, values, nonInteger, outOfRange); break;
    default:
      return Result<LabelVolume>(ErrorCode::NotALabelMap,
                                 "'" + path + "' has an unsupported pixel type.");
  }
  std::vector<char>().swap(buffer);
  if (!ok && nonInteger)
    return Result<LabelVolume>(ErrorCode::NotALabelMap,
                               "'" + path + "' holds non-integer values: it looks like an intensity "
                               "image (CT/MR), not a label map. Segment it first (e.g. in 3D Slicer's "
                               "Segment Editor) and export the segmentation as a label map.");
  if (!ok && outOfRange)
    return Result<LabelVolume>(ErrorCode::NotALabelMap,
                               "'" + path + "' holds label values outside the 32-bit integer range.");

  std::vector<SegmentInfo> segments;
  // Segment names and colours: Slicer .seg.nrrd, and plain NRRD files written by FEMesher (which
  // stores its material table with the same keys).
  if (isSeg || ext == ".nrrd" || ext == ".nhdr") segments = parseSegments(path);
  if (isSeg) {
    if (layers > 1) {
      // Merge layers (interleaved components or layer-first 4-D: both store the layer index
      // fastest). Overlap (a voxel set in two layers) is an error.
      std::vector<int32_t> merged(n, 0);
      size_t overlap = 0;
      std::map<std::pair<int, int>, size_t> overlapPairs;
      for (size_t i = 0; i < n; ++i) {
        int32_t value = 0;
        for (unsigned l = 0; l < layers; ++l) {
          const int32_t x = values[i * layers + l];
          if (x == 0) continue;
          if (value != 0) {
            ++overlap;
            ++overlapPairs[{std::min(value, x), std::max(value, x)}];
          } else {
            value = x;
          }
        }
        merged[i] = value;
      }
      if (overlap > 0) {
        auto nameOf = [&](int32_t lv) {
          for (const auto& s : segments)
            if (s.labelValue == lv) return "'" + s.name + "'";
          return std::to_string(lv);
        };
        const auto& worst = *std::max_element(
            overlapPairs.begin(), overlapPairs.end(),
            [](const auto& a, const auto& b) { return a.second < b.second; });
        return Result<LabelVolume>(
            ErrorCode::OverlappingSegments,
            "'" + path + "': segments overlap in " + std::to_string(overlap) + " voxels (e.g. " +
                nameOf(worst.first.first) + " and " + nameOf(worst.first.second) + " in " +
                std::to_string(worst.second) +
                "). A mesh needs one material per voxel: in 3D Slicer remove the overlap (Segment "
                "Editor > Logical operators) or export a label map.");
      }
      values.swap(merged);
    }
  }
  v.labels = std::move(values);

  // Labels present.
  std::set<int32_t> present;
  {
    int32_t last = std::numeric_limits<int32_t>::min();
    for (int32_t x : v.labels) {
      if (x == last) continue;
      last = x;
      present.insert(x);
      if (present.size() > 65536) break;
    }
  }
  present.erase(0);
  if (present.size() > 65535)
    return Result<LabelVolume>(ErrorCode::TooManyLabels,
                               "'" + path + "' has more than 65,535 distinct labels: it is probably not a "
                               "segmentation (an intensity image stored as integers?).");
  if (present.empty())
    return Result<LabelVolume>(ErrorCode::EmptyLabelMap,
                               "'" + path + "' holds only background (0): there is nothing to mesh. "
                               "Check that you picked the segmentation and not an empty label map.");
  for (int32_t id : present) {
    Material m;
    m.id = id;
    m.name = "label " + std::to_string(id);
    m.color = defaultLabelColor(id);
    for (const auto& s : segments)
      if (s.labelValue == id) {
        if (!s.name.empty()) m.name = s.name;
        m.color = s.color;
      }
    v.materials.push_back(m);
  }
  return v;
}

namespace {

template <class T>
Status writeTyped(const LabelVolume& g, const std::function<T(size_t)>& value, const std::string& path,
                  bool withMaterials = false) {
  using Image = itk::Image<T, 3>;
  auto image = Image::New();
  typename Image::RegionType region;
  typename Image::SizeType size;
  typename Image::SpacingType spacing;
  typename Image::PointType origin;
  typename Image::DirectionType direction;
  for (unsigned a = 0; a < 3; ++a) {
    size[a] = itk::SizeValueType(g.dims[a]);
    spacing[a] = g.spacing[a];
    origin[a] = g.origin[a];
    for (unsigned r = 0; r < 3; ++r) direction[r][a] = g.direction[3 * r + a];
  }
  region.SetSize(size);
  image->SetRegions(region);
  image->SetSpacing(spacing);
  image->SetOrigin(origin);
  image->SetDirection(direction);
  image->Allocate();
  if (withMaterials) {
    // The material table, with Slicer's segmentation keys (names and colours survive a round trip
    // through NRRD and Slicer shows them).
    auto& dict = image->GetMetaDataDictionary();
    int index = 0;
    for (const auto& m : g.materials) {
      const std::string key = "Segment" + std::to_string(index++) + "_";
      std::ostringstream color;
      color << m.color[0] << " " << m.color[1] << " " << m.color[2];
      itk::EncapsulateMetaData<std::string>(dict, key + "ID", "Segment_" + std::to_string(m.id));
      itk::EncapsulateMetaData<std::string>(dict, key + "Name", m.name);
      itk::EncapsulateMetaData<std::string>(dict, key + "Color", color.str());
      itk::EncapsulateMetaData<std::string>(dict, key + "LabelValue", std::to_string(m.id));
      itk::EncapsulateMetaData<std::string>(dict, key + "Layer", "0");
    }
  }
  T* buf = image->GetBufferPointer();
  const size_t n = g.voxelCount();
  for (size_t i = 0; i < n; ++i) buf[i] = value(i);
  return writeAtomically(path, [&](const std::string& tmp) {
    auto writer = itk::ImageFileWriter<Image>::New();
    writer->SetFileName(tmp);
    writer->SetInput(image);
    writer->SetUseCompression(true);
    try {
      writer->Update();
    } catch (const itk::ExceptionObject& e) {
      return Status(ErrorCode::WriteFailed, "Cannot write '" + path + "': " + e.GetDescription());
    }
    return Status::ok();
  });
}

}  // namespace

Status writeLabelMap(const LabelVolume& volume, const std::string& path) {
  if (volume.labels.size() != volume.voxelCount())
    return {ErrorCode::InvalidArgument, "Cannot write '" + path + "': the label map is empty."};
  const auto [mn, mx] = std::minmax_element(volume.labels.begin(), volume.labels.end());
  if (*mn >= 0 && *mx <= 255)
    return writeTyped<uint8_t>(volume, [&](size_t i) { return uint8_t(volume.labels[i]); }, path, true);
  if (*mn >= 0 && *mx <= 65535)
    return writeTyped<uint16_t>(volume, [&](size_t i) { return uint16_t(volume.labels[i]); }, path, true);
  return writeTyped<int32_t>(volume, [&](size_t i) { return volume.labels[i]; }, path, true);
}

Status writeScalarVolume(const LabelVolume& geometry, const std::vector<float>& values,
                         const std::string& path) {
  if (values.size() != geometry.voxelCount())
    return {ErrorCode::InvalidArgument, "Cannot write '" + path + "': wrong number of values."};
  return writeTyped<float>(geometry, [&](size_t i) { return values[i]; }, path);
}

LabelMapSummary summarizeLabelMap(const LabelVolume& v) {
  LabelMapSummary s;
  const auto& d = v.dims;
  const size_t n = v.voxelCount();
  const double voxelVolume = v.spacing[0] * v.spacing[1] * v.spacing[2];
  // Union-find over 6-connected voxels of equal label.
  std::vector<uint32_t> parent(n);
  std::iota(parent.begin(), parent.end(), 0u);
  auto find = [&](uint32_t x) {
    while (parent[x] != x) {
      parent[x] = parent[parent[x]];
      x = parent[x];
    }
    return x;
  };
  auto unite = [&](uint32_t a, uint32_t b) {
    a = find(a);
    b = find(b);
    if (a != b) parent[std::max(a, b)] = std::min(a, b);
  };
  std::set<std::pair<int32_t, int32_t>> pairs;
  std::map<int32_t, LabelStatistics> stats;
  const size_t sy = size_t(d[0]), sz = size_t(d[0]) * d[1];
  for (int k = 0; k < d[2]; ++k)
    for (int j = 0; j < d[1]; ++j)
      for (int i = 0; i < d[0]; ++i) {
        const size_t p = v.index(i, j, k);
        const int32_t l = v.labels[p];
        auto& st = stats[l];
        if (st.voxels == 0) {
          st.id = l;
          st.bboxMin = {i, j, k};
          st.bboxMax = {i, j, k};
        }
        ++st.voxels;
        st.bboxMin = {std::min(st.bboxMin[0], i), std::min(st.bboxMin[1], j), std::min(st.bboxMin[2], k)};
        st.bboxMax = {std::max(st.bboxMax[0], i), std::max(st.bboxMax[1], j), std::max(st.bboxMax[2], k)};
        const size_t nb[3] = {i + 1 < d[0] ? p + 1 : n, j + 1 < d[1] ? p + sy : n, k + 1 < d[2] ? p + sz : n};
        for (size_t q : nb) {
          if (q >= n) continue;
          const int32_t m = v.labels[q];
          if (m == l) unite(uint32_t(p), uint32_t(q));
          else pairs.insert({std::min(l, m), std::max(l, m)});
        }
      }
  for (size_t p = 0; p < n; ++p)
    if (find(uint32_t(p)) == p) ++stats[v.labels[p]].components;
  // 2x2x2 cells.
  for (int k = 0; k + 1 < d[2]; ++k)
    for (int j = 0; j + 1 < d[1]; ++j)
      for (int i = 0; i + 1 < d[0]; ++i) {
        int32_t lab[8];
        int c = 0;
        for (int q = 0; q < 8; ++q) {
          const int32_t x = v.at(i + (q & 1), j + ((q >> 1) & 1), k + ((q >> 2) & 1));
          bool seen = false;
          for (int r = 0; r < c; ++r) seen |= lab[r] == x;
          if (!seen) lab[c++] = x;
        }
        if (c >= 3) ++s.tripleCells;
        if (c >= 4) ++s.quadrupleCells;
      }
  for (auto& [id, st] : stats) {
    st.volumeMm3 = double(st.voxels) * voxelVolume;
    const Material* m = findMaterial(v.materials, id);
    st.name = id == 0 ? "background" : (m ? m->name : "label " + std::to_string(id));
    s.labels.push_back(st);
  }
  s.touchingPairs.assign(pairs.begin(), pairs.end());
  return s;
}

}  // namespace femesher
