// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/io/AtomicFile.h>
#include <femesher/io/LabelMapIO.h>

#include <itkImage.h>
#include <itkImageFileWriter.h>
#include <itkImageIOBase.h>
#include <itkImageIOFactory.h>
#include <itkMetaDataObject.h>
#include <zlib.h>

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

constexpr size_t kMaxLabels = 65535;
/// Label ranges up to this size are counted with a flat histogram, larger ones with a hash map.
constexpr int64_t kFlatRange = int64_t(1) << 24;

std::string trim(const std::string& s) {
  const auto a = s.find_first_not_of(" \t\r\n");
  if (a == std::string::npos) return {};
  const auto b = s.find_last_not_of(" \t\r\n");
  return s.substr(a, b - a + 1);
}

std::string quoted(const std::string& path) { return "'" + path + "'"; }

/// ITK's description without its "ITK ERROR: NrrdImageIO(0x...): " prefix, on one line.
std::string itkMessage(const itk::ExceptionObject& e) {
  std::string d = trim(e.GetDescription());
  if (d.rfind("ITK ERROR: ", 0) == 0) {
    const auto p = d.find("): ");
    if (p != std::string::npos) d = d.substr(p + 3);
  }
  std::replace(d.begin(), d.end(), '\n', ' ');
  return d;
}

Status corrupt(const std::string& path, const std::string& what) {
  return {ErrorCode::CorruptFile,
          quoted(path) + " is damaged: " + what +
              ". Re-export the file from the program that made it (or use another copy)."};
}

/// MetaImage header ("Key = Value" lines up to ElementDataFile, which is always last).
/// `headerBytes` receives the offset of the data for ElementDataFile = LOCAL.
std::map<std::string, std::string> readMetaHeader(const std::string& path, uintmax_t& headerBytes) {
  std::map<std::string, std::string> h;
  std::ifstream in(path, std::ios::binary);
  std::string line;
  headerBytes = 0;
  while (headerBytes < (1u << 20) && std::getline(in, line)) {
    headerBytes += line.size() + 1;
    const auto pos = line.find('=');
    if (pos == std::string::npos) continue;
    const std::string key = trim(line.substr(0, pos));
    h[key] = trim(line.substr(pos + 1));
    if (key == "ElementDataFile") break;
  }
  return h;
}

/// A MetaImage header that lies about its data. ITK trusts CompressedDataSize and zero-fills
/// whatever it did not decode, so this must be checked before ITK reads the file.
Status checkMetaImage(const std::string& path) {
  uintmax_t headerBytes = 0;
  const auto h = readMetaHeader(path, headerBytes);
  const auto dataIt = h.find("ElementDataFile");
  if (dataIt == h.end()) return Status::ok();  // ITK reports a header without data itself
  const std::string dataFile = dataIt->second;
  if (dataFile == "LIST" || dataFile.find('%') != std::string::npos) return Status::ok();
  std::error_code ec;
  uintmax_t available = 0;
  std::string dataName;
  if (dataFile == "LOCAL") {
    const uintmax_t size = fs::file_size(path, ec);
    available = size >= headerBytes ? size - headerBytes : 0;
    dataName = "the data after its header";
  } else {
    fs::path dataPath(dataFile);
    if (dataPath.is_relative()) dataPath = fs::path(path).parent_path() / dataPath;
    available = fs::file_size(dataPath, ec);
    if (ec)
      return {ErrorCode::CorruptFile,
              quoted(path) + " refers to the data file '" + dataPath.string() +
                  "', which is missing or unreadable. Keep the .mhd and its data file together "
                  "in one folder (or convert to a single .nrrd/.mha file)."};
    dataName = "'" + dataPath.filename().string() + "'";
  }
  const auto compressed = h.find("CompressedData");
  const bool isCompressed = compressed != h.end() && (compressed->second == "True" ||
                                                      compressed->second == "true" ||
                                                      compressed->second == "TRUE");
  if (isCompressed) {
    const auto cs = h.find("CompressedDataSize");
    if (cs == h.end()) return Status::ok();
    uintmax_t declared = 0;
    try {
      declared = std::stoull(cs->second);
    } catch (...) {
      return corrupt(path, "its CompressedDataSize '" + cs->second + "' is not a number");
    }
    if (declared != available)
      return corrupt(path, "its header says CompressedDataSize = " + cs->second + " but " + dataName +
                               " holds " + std::to_string(available) +
                               " bytes, so a reader would silently fill the missing voxels with 0");
    return Status::ok();
  }
  // Raw data: the data must hold every voxel.
  static const std::map<std::string, uintmax_t> bytes = {
      {"MET_UCHAR", 1}, {"MET_CHAR", 1},  {"MET_USHORT", 2}, {"MET_SHORT", 2},
      {"MET_UINT", 4},  {"MET_INT", 4},   {"MET_FLOAT", 4},  {"MET_ULONG", 8},
      {"MET_LONG", 8},  {"MET_DOUBLE", 8}, {"MET_ULONG_LONG", 8}, {"MET_LONG_LONG", 8}};
  const auto et = h.find("ElementType");
  const auto ds = h.find("DimSize");
  if (et == h.end() || ds == h.end() || !bytes.count(et->second)) return Status::ok();
  std::istringstream dims(ds->second);
  uintmax_t count = 1, d = 0;
  while (dims >> d) count *= d;
  uintmax_t channels = 1;
  if (const auto c = h.find("ElementNumberOfChannels"); c != h.end())
    channels = std::max<uintmax_t>(1, std::strtoull(c->second.c_str(), nullptr, 10));
  const uintmax_t expected = count * bytes.at(et->second) * channels;
  if (available < expected)
    return corrupt(path, "its header describes " + std::to_string(expected) + " bytes of voxels but " +
                             dataName + " holds only " + std::to_string(available) + " bytes");
  return Status::ok();
}

/// NIfTI (.nii, .nii.gz): ITK reads a file whose data is shorter than its header says (or whose
/// gzip stream is cut) without complaint, zero-filling the rest. Count the bytes that are really
/// there (decompressing a .nii.gz once) and compare with the header.
Status checkNifti(const std::string& path) {
  gzFile f = gzopen(path.c_str(), "rb");
  if (!f) return Status::ok();  // ITK reports unreadable files itself
  struct Closer {
    gzFile f;
    ~Closer() { gzclose(f); }
  } closer{f};
  unsigned char h[540];
  const int got = gzread(f, h, sizeof(h));
  if (got < 348) return corrupt(path, "it is shorter than a NIfTI header");
  auto get = [&](size_t off, size_t n, bool swap) {
    unsigned char b[8];
    for (size_t i = 0; i < n; ++i) b[i] = h[off + (swap ? n - 1 - i : i)];
    return std::vector<unsigned char>(b, b + n);
  };
  auto i32 = [&](size_t off, bool swap) { int32_t x; std::memcpy(&x, get(off, 4, swap).data(), 4); return x; };
  auto i16 = [&](size_t off, bool swap) { int16_t x; std::memcpy(&x, get(off, 2, swap).data(), 2); return x; };
  auto i64 = [&](size_t off, bool swap) { int64_t x; std::memcpy(&x, get(off, 8, swap).data(), 8); return x; };
  auto f32 = [&](size_t off, bool swap) { float x; std::memcpy(&x, get(off, 4, swap).data(), 4); return x; };
  bool swap = false;
  int32_t sizeofHdr = i32(0, false);
  if (sizeofHdr != 348 && sizeofHdr != 540) {
    swap = true;
    sizeofHdr = i32(0, true);
  }
  uintmax_t voxels = 1, bitpix = 0, offset = 0;
  if (sizeofHdr == 348) {
    const int nd = i16(40, swap);
    if (nd < 1 || nd > 7) return Status::ok();
    for (int d = 1; d <= nd; ++d) voxels *= uintmax_t(std::max<int16_t>(1, i16(40 + 2 * size_t(d), swap)));
    bitpix = uintmax_t(std::max<int16_t>(0, i16(72, swap)));
    offset = uintmax_t(std::max(0.f, f32(108, swap)));
    if (offset == 0) return Status::ok();  // a .hdr/.img pair: data elsewhere
  } else if (sizeofHdr == 540 && got == 540) {
    const int64_t nd = i64(16, swap);
    if (nd < 1 || nd > 7) return Status::ok();
    for (int d = 1; d <= nd; ++d) voxels *= uintmax_t(std::max<int64_t>(1, i64(16 + 8 * size_t(d), swap)));
    bitpix = uintmax_t(std::max<int16_t>(0, i16(14, swap)));
    offset = uintmax_t(std::max<int64_t>(0, i64(168, swap)));
  } else {
    return Status::ok();  // not NIfTI: ITK decides
  }
  const uintmax_t expected = offset + voxels * bitpix / 8;
  uintmax_t available = uintmax_t(got);
  std::vector<char> chunk(1 << 18);
  while (available < expected) {
    const int n = gzread(f, chunk.data(), unsigned(chunk.size()));
    if (n <= 0) break;
    available += uintmax_t(n);
  }
  int err = Z_OK;
  const char* message = gzerror(f, &err);
  if (err != Z_OK && err != Z_STREAM_END)
    return corrupt(path, std::string("its compressed data is cut off or damaged (zlib: ") + message + ")");
  if (available < expected)
    return corrupt(path, "its header describes " + std::to_string(expected) + " bytes but the file holds only " +
                             std::to_string(available) + " (truncated); a reader would fill the rest with 0");
  return Status::ok();
}

struct SegmentInfo {
  int index = 0;  ///< N in Segment<N>_...
  std::string id, name;
  std::array<double, 3> color{{0.5, 0.5, 0.5}};
  bool hasColor = false;
  int32_t labelValue = 1;  ///< old .seg.nrrd files have no LabelValue: binary layers
  int layer = 0;
};

/// Slicer segment keys (Segment<N>_ID/_Name/_Color/_LabelValue/_Layer) from ITK's dictionary.
std::vector<SegmentInfo> parseSegments(const itk::MetaDataDictionary& dict) {
  std::map<int, SegmentInfo> segs;
  for (const std::string& key : dict.GetKeys()) {
    if (key.rfind("Segment", 0) != 0) continue;
    const auto us = key.find('_');
    if (us == std::string::npos || us <= 7) continue;
    const std::string number = key.substr(7, us - 7);
    if (number.find_first_not_of("0123456789") != std::string::npos) continue;
    std::string value;
    if (!itk::ExposeMetaData<std::string>(dict, key, value)) continue;
    value = trim(value);
    const int n = std::atoi(number.c_str());
    SegmentInfo& s = segs[n];
    s.index = n;
    const std::string field = key.substr(us + 1);
    if (field == "ID") s.id = value;
    else if (field == "Name") s.name = value;
    else if (field == "LabelValue") s.labelValue = std::atoi(value.c_str());
    else if (field == "Layer") s.layer = std::atoi(value.c_str());
    else if (field == "Color") {
      std::istringstream c(value);
      std::array<double, 3> rgb{};
      if (c >> rgb[0] >> rgb[1] >> rgb[2]) {
        for (double& x : rgb) x = std::clamp(x, 0.0, 1.0);
        s.color = rgb;
        s.hasColor = true;
      }
    }
  }
  std::vector<SegmentInfo> out;
  for (auto& [n, s] : segs)
    if (!s.id.empty() || !s.name.empty()) out.push_back(s);
  return out;
}

enum class Conversion { Ok, NonInteger, OutOfRange };

/// Native buffer -> int32, in one loop per type.
template <class T>
Conversion convertBuffer(const void* data, size_t n, std::vector<int32_t>& out) {
  const T* p = static_cast<const T*>(data);
  out.resize(n);
  int32_t* o = out.data();
  if constexpr (std::is_floating_point_v<T>) {
    for (size_t i = 0; i < n; ++i) {
      const T v = p[i];
      if (!(v == std::floor(v))) return Conversion::NonInteger;  // also NaN and infinities
      if (v > T(2147483647.0) || v < T(-2147483648.0)) return Conversion::OutOfRange;
      o[i] = int32_t(v);
    }
  } else if constexpr (sizeof(T) < 4 || (sizeof(T) == 4 && std::is_signed_v<T>)) {
    for (size_t i = 0; i < n; ++i) o[i] = int32_t(p[i]);
  } else {
    bool bad = false;
    for (size_t i = 0; i < n; ++i) {
      const T v = p[i];
      if constexpr (std::is_signed_v<T>)
        bad |= v < T(std::numeric_limits<int32_t>::min()) || v > T(std::numeric_limits<int32_t>::max());
      else
        bad |= v > T(std::numeric_limits<int32_t>::max());
      o[i] = int32_t(v);
    }
    if (bad) return Conversion::OutOfRange;
  }
  return Conversion::Ok;
}

/// Distinct values of `labels`, sorted; stops counting after `limit` distinct values.
std::vector<int32_t> distinctLabels(const std::vector<int32_t>& labels, size_t limit) {
  std::vector<int32_t> out;
  if (labels.empty()) return out;
  const auto [mnIt, mxIt] = std::minmax_element(labels.begin(), labels.end());
  const int64_t mn = *mnIt, mx = *mxIt;
  if (mx - mn < kFlatRange) {
    std::vector<uint8_t> seen(size_t(mx - mn + 1), 0);
    for (int32_t x : labels) seen[size_t(int64_t(x) - mn)] = 1;
    for (size_t i = 0; i < seen.size(); ++i)
      if (seen[i]) out.push_back(int32_t(int64_t(i) + mn));
    return out;
  }
  std::unordered_set<int32_t> seen;
  int32_t last = labels[0];
  seen.insert(last);
  for (int32_t x : labels) {
    if (x == last) continue;
    last = x;
    seen.insert(x);
    if (seen.size() > limit) break;
  }
  out.assign(seen.begin(), seen.end());
  std::sort(out.begin(), out.end());
  return out;
}

/// Merge the layers of a .seg.nrrd (layer index fastest in `values`) into one label per voxel.
/// Material ids are the segments' LabelValues when these are unique across layers, otherwise the
/// segments are numbered 1, 2, ... in header order (`segments[].labelValue` is updated to the
/// material id). A voxel set in two layers is an OverlappingSegments error.
Result<std::vector<int32_t>> mergeLayers(const std::string& path, const std::vector<int32_t>& values,
                                         size_t n, unsigned layers, std::vector<SegmentInfo>& segments) {
  std::set<int32_t> seenValues;
  bool unique = true;
  for (const auto& s : segments) unique &= seenValues.insert(s.labelValue).second;
  // Per layer: stored value -> material id (flat table; values of a .seg.nrrd are small).
  int32_t maxStored = 0;
  for (int32_t x : values) {
    if (x < 0)
      return Result<std::vector<int32_t>>(
          ErrorCode::NotALabelMap, quoted(path) + " holds negative values in a segmentation layer; "
                                                  "re-export the segmentation from 3D Slicer.");
    maxStored = std::max(maxStored, x);
  }
  if (maxStored >= (1 << 20))
    return Result<std::vector<int32_t>>(
        ErrorCode::NotALabelMap,
        quoted(path) + " has segmentation layers with values up to " + std::to_string(maxStored) +
            "; export the segmentation as a label map from 3D Slicer instead.");
  const size_t width = size_t(maxStored) + 1;
  std::vector<int32_t> lut(width * layers);
  for (unsigned l = 0; l < layers; ++l)
    for (size_t x = 0; x < width; ++x) lut[l * width + x] = int32_t(x);
  for (size_t s = 0; s < segments.size(); ++s) {
    SegmentInfo& seg = segments[s];
    const int32_t material = unique ? seg.labelValue : int32_t(s + 1);
    if (seg.layer >= 0 && unsigned(seg.layer) < layers && seg.labelValue >= 0 &&
        size_t(seg.labelValue) < width)
      lut[size_t(seg.layer) * width + size_t(seg.labelValue)] = material;
    seg.labelValue = material;
  }
  std::vector<int32_t> merged(n, 0);
  std::map<std::pair<int32_t, int32_t>, size_t> overlapPairs;
  size_t overlap = 0;
  for (size_t i = 0; i < n; ++i) {
    const int32_t* v = values.data() + i * layers;
    int32_t m = 0;
    bool twice = false;
    for (unsigned l = 0; l < layers; ++l) {
      if (v[l] == 0) continue;
      const int32_t x = lut[l * width + size_t(v[l])];
      if (m != 0 && x != m) {
        ++overlapPairs[{std::min(m, x), std::max(m, x)}];
        twice = true;
      } else {
        m = x;
      }
    }
    overlap += twice;
    merged[i] = m;
  }
  if (overlap > 0) {
    auto nameOf = [&](int32_t id) {
      for (const auto& s : segments)
        if (s.labelValue == id) return "'" + (s.name.empty() ? s.id : s.name) + "'";
      return "label " + std::to_string(id);
    };
    std::string pairsText;
    int listed = 0;
    for (const auto& [pair, count] : overlapPairs) {
      if (listed++ == 3) {
        pairsText += ", ...";
        break;
      }
      if (!pairsText.empty()) pairsText += ", ";
      pairsText += "segments " + nameOf(pair.first) + " and " + nameOf(pair.second) + " overlap in " +
                   std::to_string(count) + " voxels";
    }
    return Result<std::vector<int32_t>>(
        ErrorCode::OverlappingSegments,
        quoted(path) + ": " + pairsText + " (" + std::to_string(overlap) +
            " voxels belong to more than one segment). A mesh needs one material per voxel: in 3D "
            "Slicer use Segment Editor > Logical operators to remove the overlap, or export a label "
            "map (Segmentations > Export to label map) and mesh that.");
  }
  return merged;
}

}  // namespace

Result<LabelVolume> readLabelMap(const std::string& path) {
  using R = Result<LabelVolume>;
  std::error_code ec;
  if (path.empty()) return R(ErrorCode::FileNotFound, "No input file was given; give a label map path.");
  if (!fs::exists(path, ec))
    return R(ErrorCode::FileNotFound,
             quoted(path) + " does not exist. Check the path and the file name.");
  if (fs::is_directory(path, ec))
    return R(ErrorCode::UnreadableFile,
             quoted(path) + " is a folder, not a label map file (.nrrd, .nii.gz, .mha, .seg.nrrd). "
                            "Convert DICOM series to NRRD or NIfTI first (e.g. in 3D Slicer).");
  {
    std::ifstream probe(path, std::ios::binary);
    if (!probe)
      return R(ErrorCode::UnreadableFile,
               quoted(path) + " cannot be opened (permission denied?). Check the file's permissions.");
  }
  if (fs::file_size(path, ec) == 0)
    return R(ErrorCode::UnreadableFile,
             quoted(path) + " is an empty file (0 bytes). Export the label map again.");
  const std::string ext = fileExtension(path);
  if (ext == ".mhd" || ext == ".mha")
    if (Status s = checkMetaImage(path); !s) return s;
  if (ext == ".nii" || ext == ".nii.gz")
    if (Status s = checkNifti(path); !s) return s;

  itk::ImageIOBase::Pointer io =
      itk::ImageIOFactory::CreateImageIO(path.c_str(), itk::ImageIOFactory::IOFileModeEnum::ReadMode);
  if (!io)
    return R(ErrorCode::UnreadableFile,
             quoted(path) + " is not an image FEMesher can read: its content matches no supported "
                            "format (.nrrd, .nhdr, .nii, .nii.gz, .mha, .mhd, .seg.nrrd). Check that it "
                            "is a label map and not a renamed or damaged file.");
  io->SetFileName(path);
  try {
    io->ReadImageInformation();
  } catch (const itk::ExceptionObject& e) {
    return R(ErrorCode::UnreadableFile, quoted(path) + " has a header that cannot be read (" +
                                            itkMessage(e) +
                                            "). Re-export the label map from the program that made it.");
  }
  const bool isSeg = ext == ".seg.nrrd";
  const unsigned dim = io->GetNumberOfDimensions();
  const unsigned comps = io->GetNumberOfComponents();
  unsigned layers = 1, spatial0 = 0;
  if (dim < 3)
    return R(ErrorCode::NotALabelMap,
             quoted(path) + " is a " + std::to_string(dim) +
                 "-D image; FEMesher needs a 3-D label map (a volume, not a single slice).");
  if (dim > 3) {
    if (isSeg && dim == 4 && comps == 1) {
      layers = unsigned(io->GetDimensions(0));  // layer axis first ("list" kind)
      spatial0 = 1;
    } else {
      for (unsigned a = 3; a < dim; ++a)
        if (io->GetDimensions(a) != 1)
          return R(ErrorCode::NotALabelMap,
                   quoted(path) + " is a " + std::to_string(dim) +
                       "-D image (e.g. a time series); FEMesher needs a 3-D label map. Extract one "
                       "volume first.");
    }
  }
  if (comps > 1) {
    if (!isSeg)
      return R(ErrorCode::NotALabelMap,
               quoted(path) + " has " + std::to_string(comps) +
                   " values per voxel (a vector or colour image); FEMesher needs one integer label per "
                   "voxel.");
    layers = comps;  // ITK reads the layer axis of a .seg.nrrd as pixel components
  }

  LabelVolume v;
  v.sourcePath = path;
  for (unsigned a = 0; a < 3; ++a) {
    const unsigned axis = a + spatial0;
    v.dims[a] = int(io->GetDimensions(axis));
    v.spacing[a] = io->GetSpacing(axis);
    v.origin[a] = io->GetOrigin(axis);
    const std::vector<double> dir = io->GetDirection(axis);
    for (unsigned r = 0; r < 3; ++r) v.direction[3 * r + a] = dir.size() > r + spatial0 ? dir[r + spatial0] : 0.0;
    if (!(v.spacing[a] > 0) || !std::isfinite(v.spacing[a]))
      return R(ErrorCode::CorruptFile, quoted(path) + " has a voxel spacing of " +
                                           std::to_string(v.spacing[a]) + " mm along axis " +
                                           std::to_string(a) + "; fix the header's spacing.");
  }
  if (std::fabs(v.directionDeterminant()) < 1e-6)
    return R(ErrorCode::CorruptFile, quoted(path) + " has a degenerate direction matrix (axes not "
                                                    "independent); fix the header's orientation.");
  const size_t n = v.voxelCount();
  if (n == 0) return R(ErrorCode::EmptyLabelMap, quoted(path) + " has no voxels.");
  const size_t total = n * layers;

  std::vector<int32_t> values;
  Conversion conversion = Conversion::Ok;
  {
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
      return corrupt(path, "its voxel data could not be read completely (" + itkMessage(e) +
                               "); the file is probably truncated or its compressed data is damaged");
    } catch (const std::bad_alloc&) {
      return R(ErrorCode::UnreadableFile, quoted(path) + " is too large to load into memory.");
    }
    if (buffer.size() < total * io->GetComponentSize())
      return corrupt(path, "it holds fewer voxels than its header says");
    using CT = itk::IOComponentEnum;
    const void* data = buffer.data();
    switch (io->GetComponentType()) {
      case CT::UCHAR: conversion = convertBuffer<uint8_t>(data, total, values); break;
      case CT::CHAR: conversion = convertBuffer<int8_t>(data, total, values); break;
      case CT::USHORT: conversion = convertBuffer<uint16_t>(data, total, values); break;
      case CT::SHORT: conversion = convertBuffer<int16_t>(data, total, values); break;
      case CT::UINT: conversion = convertBuffer<uint32_t>(data, total, values); break;
      case CT::INT: conversion = convertBuffer<int32_t>(data, total, values); break;
      case CT::ULONG: conversion = convertBuffer<unsigned long>(data, total, values); break;
      case CT::LONG: conversion = convertBuffer<long>(data, total, values); break;
      case CT::ULONGLONG: conversion = convertBuffer<unsigned long long>(data, total, values); break;
      case CT::LONGLONG: conversion = convertBuffer<long long>(data, total, values); break;
      case CT::FLOAT: conversion = convertBuffer<float>(data, total, values); break;
      case CT::DOUBLE: conversion = convertBuffer<double>(data, total, values); break;
      default:
        return R(ErrorCode::NotALabelMap,
                 quoted(path) + " has an unsupported pixel type (" +
                     itk::ImageIOBase::GetComponentTypeAsString(io->GetComponentType()) +
                     "); save the label map with integer voxels.");
    }
  }
  if (conversion == Conversion::NonInteger)
    return R(ErrorCode::NotALabelMap,
             quoted(path) + " holds non-integer values: it looks like a CT/intensity image, not labels. "
                            "Segment it first (e.g. in 3D Slicer's Segment Editor) and export the "
                            "segmentation as a label map.");
  if (conversion == Conversion::OutOfRange)
    return R(ErrorCode::NotALabelMap,
             quoted(path) + " holds values outside the 32-bit integer range, which cannot be labels. "
                            "Check that this is a label map; renumber the labels if it is.");

  // Segment names and colours: Slicer .seg.nrrd, and NRRD/MetaImage files written by FEMesher
  // (which stores its material table under the same keys).
  std::vector<SegmentInfo> segments = parseSegments(io->GetMetaDataDictionary());
  if (layers > 1) {
    auto merged = mergeLayers(path, values, n, layers, segments);
    if (!merged) return merged.status();
    values = std::move(merged).value();
  } else {
    // A single layer: stored values are the LabelValues; ignore segments of other layers.
    segments.erase(std::remove_if(segments.begin(), segments.end(),
                                  [](const SegmentInfo& s) { return s.layer != 0; }),
                   segments.end());
  }
  v.labels = std::move(values);

  std::vector<int32_t> present = distinctLabels(v.labels, kMaxLabels + 1);
  present.erase(std::remove(present.begin(), present.end(), 0), present.end());
  if (present.size() > kMaxLabels)
    return R(ErrorCode::TooManyLabels,
             quoted(path) + " has more than 65,535 distinct labels: it is probably an intensity image "
                            "stored as integers, not a segmentation. Segment it first, or merge labels.");
  if (present.empty())
    return R(ErrorCode::EmptyLabelMap,
             quoted(path) + " holds only background (0): there is nothing to mesh. Check that you "
                            "picked the segmentation and that it is not empty.");
  v.materials.reserve(present.size());
  for (int32_t id : present) {
    Material m;
    m.id = id;
    m.name = "label " + std::to_string(id);
    m.color = defaultLabelColor(id);
    for (const auto& s : segments)
      if (s.labelValue == id) {
        if (!s.name.empty()) m.name = s.name;
        if (s.hasColor) m.color = s.color;
        break;
      }
    v.materials.push_back(m);
  }
  return v;
}

namespace {

/// A detached header (.mhd, .nhdr) written under a temporary name refers to a data file with the
/// same temporary stem: give the data file its final name and patch the header.
Status renameCompanionData(const std::string& tmpHeader, const std::string& finalPath) {
  const std::string ext = fileExtension(finalPath);
  if (ext != ".mhd" && ext != ".nhdr") return Status::ok();
  const std::string key = ext == ".mhd" ? "ElementDataFile" : "data file";
  const fs::path tmp(tmpHeader), fin(finalPath);
  const std::string tmpStem = tmp.filename().string().substr(0, tmp.filename().string().size() - ext.size());
  const std::string finStem = fin.filename().string().substr(0, fin.filename().string().size() - ext.size());
  std::ifstream in(tmpHeader, std::ios::binary);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  in.close();
  size_t pos = text.find(key);
  while (pos != std::string::npos && pos != 0 && text[pos - 1] != '\n') pos = text.find(key, pos + 1);
  if (pos == std::string::npos) return Status::ok();
  const size_t valueStart = text.find_first_not_of(" =:", pos + key.size());
  const size_t lineEnd = text.find('\n', pos);
  if (valueStart == std::string::npos || lineEnd == std::string::npos || valueStart > lineEnd) return Status::ok();
  const std::string value = trim(text.substr(valueStart, lineEnd - valueStart));
  if (value.rfind(tmpStem, 0) != 0) return Status::ok();
  const std::string newValue = finStem + value.substr(tmpStem.size());
  std::error_code ec;
  fs::rename(tmp.parent_path() / value, tmp.parent_path() / newValue, ec);
  if (ec)
    return {ErrorCode::WriteFailed, "Cannot write the data file of " + quoted(finalPath) + ": " + ec.message()};
  text = text.substr(0, valueStart) + newValue + text.substr(lineEnd);
  std::ofstream out(tmpHeader, std::ios::binary | std::ios::trunc);
  out << text;
  out.close();
  if (!out) return {ErrorCode::WriteFailed, "Cannot write " + quoted(finalPath) + ": check free disk space."};
  return Status::ok();
}

template <class T, class ValueFn>
Status writeTyped(const LabelVolume& g, ValueFn value, const std::string& path, bool withMaterials) {
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
    // The material table under Slicer's segmentation keys: names and colours survive a round trip
    // through NRRD, and Slicer shows them when the file is loaded as a segmentation.
    auto& dict = image->GetMetaDataDictionary();
    int index = 0;
    for (const auto& m : g.materials) {
      const std::string key = "Segment" + std::to_string(index++) + "_";
      std::ostringstream color;
      color.precision(6);
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
      return Status(ErrorCode::WriteFailed, "Cannot write " + quoted(path) + ": " + itkMessage(e) +
                                                ". Check the folder's permissions and free disk space.");
    }
    return renameCompanionData(tmp, path);
  });
}

Status checkWritable(const LabelVolume& g, size_t valueCount, const std::string& path) {
  if (g.dims[0] <= 0 || g.dims[1] <= 0 || g.dims[2] <= 0 || valueCount != g.voxelCount())
    return {ErrorCode::InvalidArgument, "Cannot write " + quoted(path) + ": the volume is empty or its "
                                        "value count does not match its dimensions."};
  for (double s : g.spacing)
    if (!(s > 0)) return {ErrorCode::InvalidArgument, "Cannot write " + quoted(path) + ": non-positive spacing."};
  if (!itk::ImageIOFactory::CreateImageIO(path.c_str(), itk::ImageIOFactory::IOFileModeEnum::WriteMode))
    return {ErrorCode::InvalidArgument,
            "Cannot write " + quoted(path) + ": unknown image format; use .nrrd, .nii.gz, .nii, .mha or .mhd."};
  return Status::ok();
}

}  // namespace

Status writeLabelMap(const LabelVolume& volume, const std::string& path) {
  if (Status s = checkWritable(volume, volume.labels.size(), path); !s) return s;
  const auto [mn, mx] = std::minmax_element(volume.labels.begin(), volume.labels.end());
  const auto& l = volume.labels;
  if (*mn >= 0 && *mx <= 255)
    return writeTyped<uint8_t>(volume, [&](size_t i) { return uint8_t(l[i]); }, path, true);
  if (*mn >= 0 && *mx <= 65535)
    return writeTyped<uint16_t>(volume, [&](size_t i) { return uint16_t(l[i]); }, path, true);
  return writeTyped<int32_t>(volume, [&](size_t i) { return l[i]; }, path, true);
}

Status writeScalarVolume(const LabelVolume& geometry, const std::vector<float>& values,
                         const std::string& path) {
  if (Status s = checkWritable(geometry, values.size(), path); !s) return s;
  return writeTyped<float>(geometry, [&](size_t i) { return values[i]; }, path, false);
}

namespace {

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
