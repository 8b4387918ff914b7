// SPDX-License-Identifier: GPL-3.0-or-later
// Reading label maps with ITK, Slicer .seg.nrrd layers merged (declared in LabelMapIO.h).
#include <femesher/io/AtomicFile.h>
#include <femesher/io/LabelMapFiles.h>
#include <femesher/io/LabelMapIO.h>

#include <itkImageIOBase.h>
#include <itkImageIOFactory.h>
#include <itkMetaDataObject.h>

#include <algorithm>
#include <array>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <new>
#include <set>
#include <sstream>

namespace femesher {

namespace fs = std::filesystem;

namespace {

using labelio::corrupt;
using labelio::itkMessage;
using labelio::quoted;
using labelio::trim;

struct SegmentInfo {
  int index = 0;  ///< N in Segment<N>_...
  std::string id, name;
  std::array<double, 3> color{{0.5, 0.5, 0.5}};
  bool hasColor = false;
  int32_t labelValue = 1;  ///< old .seg.nrrd files have no LabelValue: binary layers
  bool hasLabelValue = false;
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
    else if (field == "LabelValue") {
      s.labelValue = std::atoi(value.c_str());
      s.hasLabelValue = true;
    }
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

/// How a message names a segment: 'Name' (ID Segment_1).
std::string segmentName(const SegmentInfo& s) {
  std::string text = "'" + (s.name.empty() ? s.id : s.name) + "'";
  if (!s.id.empty() && !s.name.empty()) text += " (ID " + s.id + ")";
  return text;
}

/// Two segments with the same LabelValue in the same layer claim the same voxels: every voxel of
/// that value would belong to both (an overlap the header makes, which 3D Slicer never writes).
/// OverlappingSegments naming both segments, the value and the layer. Segments without an
/// explicit LabelValue (old binary-layer files) are not compared.
Status checkDuplicateLabelValues(const std::string& path, const std::vector<SegmentInfo>& segments) {
  std::map<std::pair<int, int32_t>, const SegmentInfo*> owner;
  for (const SegmentInfo& s : segments) {
    if (!s.hasLabelValue) continue;
    const auto [it, inserted] = owner.emplace(std::make_pair(s.layer, s.labelValue), &s);
    if (inserted) continue;
    return {ErrorCode::OverlappingSegments,
            quoted(path) + ": segments " + segmentName(*it->second) + " and " + segmentName(s) +
                " both have LabelValue " + std::to_string(s.labelValue) + " in layer " +
                std::to_string(s.layer) + ", so every voxel of value " +
                std::to_string(s.labelValue) + " would belong to both (a header 3D Slicer does "
                "not write). Open the segmentation in 3D Slicer, check or remove one of the two "
                "segments and re-export it (or export a label map: Segmentations > Export to "
                "label map) and mesh that."};
  }
  return Status::ok();
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

/// Problems with the path itself, and headers that lie about their data (before ITK reads it).
Status checkInputFile(const std::string& path) {
  std::error_code ec;
  if (path.empty()) return {ErrorCode::FileNotFound, "No input file was given; give a label map path."};
  if (!fs::exists(path, ec))
    return {ErrorCode::FileNotFound,
            quoted(path) + " does not exist. Check the path and the file name."};
  if (fs::is_directory(path, ec))
    return {ErrorCode::UnreadableFile,
            quoted(path) + " is a folder, not a label map file (.nrrd, .nii.gz, .mha, .seg.nrrd). "
                           "Convert DICOM series to NRRD or NIfTI first (e.g. in 3D Slicer)."};
  {
    std::ifstream probe(path, std::ios::binary);
    if (!probe)
      return {ErrorCode::UnreadableFile,
              quoted(path) + " cannot be opened (permission denied?). Check the file's permissions."};
  }
  if (fs::file_size(path, ec) == 0)
    return {ErrorCode::UnreadableFile,
            quoted(path) + " is an empty file (0 bytes). Export the label map again."};
  const std::string ext = fileExtension(path);
  if (ext == ".mhd" || ext == ".mha")
    if (Status s = labelio::checkMetaImage(path); !s) return s;
  if (ext == ".nii" || ext == ".nii.gz")
    if (Status s = labelio::checkNifti(path); !s) return s;
  if (ext == ".nrrd" || ext == ".nhdr" || ext == ".seg.nrrd")
    if (Status s = labelio::checkNrrd(path); !s) return s;
  return Status::ok();
}

/// How the voxels of the image ITK describes hold labels: the first spatial axis, and the values
/// per voxel (the layers of a .seg.nrrd, else 1).
struct Layout {
  unsigned spatial0 = 0;
  unsigned layers = 1;
};

Result<Layout> layoutOf(const itk::ImageIOBase& io, const std::string& path) {
  const bool isSeg = fileExtension(path) == ".seg.nrrd";
  const unsigned dim = io.GetNumberOfDimensions();
  const unsigned comps = io.GetNumberOfComponents();
  Layout layout;
  if (dim < 3)
    return Result<Layout>(ErrorCode::NotALabelMap,
                          quoted(path) + " is a " + std::to_string(dim) +
                              "-D image; FEMesher needs a 3-D label map (a volume, not a single slice).");
  if (dim > 3) {
    if (isSeg && dim == 4 && comps == 1) {
      layout.layers = unsigned(io.GetDimensions(0));  // layer axis first ("list" kind)
      layout.spatial0 = 1;
    } else {
      for (unsigned a = 3; a < dim; ++a)
        if (io.GetDimensions(a) != 1)
          return Result<Layout>(ErrorCode::NotALabelMap,
                                quoted(path) + " is a " + std::to_string(dim) +
                                    "-D image (e.g. a time series); FEMesher needs a 3-D label map. "
                                    "Extract one volume first.");
    }
  }
  if (comps > 1) {
    if (!isSeg)
      return Result<Layout>(ErrorCode::NotALabelMap,
                            quoted(path) + " has " + std::to_string(comps) +
                                " values per voxel (a vector or colour image); FEMesher needs one "
                                "integer label per voxel.");
    layout.layers = comps;  // ITK reads the layer axis of a .seg.nrrd as pixel components
  }
  return layout;
}

/// Dimensions, spacing, origin and direction of the three spatial axes.
LabelVolume geometryOf(const itk::ImageIOBase& io, unsigned spatial0) {
  LabelVolume v;
  for (unsigned a = 0; a < 3; ++a) {
    const unsigned axis = a + spatial0;
    v.dims[a] = int(io.GetDimensions(axis));
    v.spacing[a] = io.GetSpacing(axis);
    v.origin[a] = io.GetOrigin(axis);
    const std::vector<double> dir = io.GetDirection(axis);
    for (unsigned r = 0; r < 3; ++r)
      v.direction[3 * r + a] = dir.size() > r + spatial0 ? dir[r + spatial0] : 0.0;
  }
  return v;
}

/// The VoxelType of an ITK component type; false for types labels cannot have.
bool voxelTypeOfComponent(itk::IOComponentEnum type, VoxelType& out) {
  using CT = itk::IOComponentEnum;
  switch (type) {
    case CT::UCHAR: out = voxelTypeOf<uint8_t>(); return true;
    case CT::CHAR: out = voxelTypeOf<int8_t>(); return true;
    case CT::USHORT: out = voxelTypeOf<uint16_t>(); return true;
    case CT::SHORT: out = voxelTypeOf<int16_t>(); return true;
    case CT::UINT: out = voxelTypeOf<uint32_t>(); return true;
    case CT::INT: out = voxelTypeOf<int32_t>(); return true;
    case CT::ULONG: out = voxelTypeOf<unsigned long>(); return true;
    case CT::LONG: out = voxelTypeOf<long>(); return true;
    case CT::ULONGLONG: out = voxelTypeOf<unsigned long long>(); return true;
    case CT::LONGLONG: out = voxelTypeOf<long long>(); return true;
    case CT::FLOAT: out = voxelTypeOf<float>(); return true;
    case CT::DOUBLE: out = voxelTypeOf<double>(); return true;
    default: return false;
  }
}

/// All `total` values of the image (`layers` per voxel, layer fastest) as int32.
Result<std::vector<int32_t>> readValues(itk::ImageIOBase& io, size_t total, const std::string& path) {
  using R = Result<std::vector<int32_t>>;
  VoxelType type;
  std::vector<char> buffer;
  try {
    buffer.resize(io.GetImageSizeInBytes());
    const unsigned dim = io.GetNumberOfDimensions();
    itk::ImageIORegion region(dim);
    for (unsigned a = 0; a < dim; ++a) {
      region.SetIndex(a, 0);
      region.SetSize(a, io.GetDimensions(a));
    }
    io.SetIORegion(region);
    io.Read(buffer.data());
  } catch (const itk::ExceptionObject& e) {
    return corrupt(path, "its voxel data could not be read completely (" + itkMessage(e) +
                             "); the file is probably truncated or its compressed data is damaged");
  } catch (const std::bad_alloc&) {
    return R(ErrorCode::UnreadableFile, quoted(path) + " is too large to load into memory.");
  }
  if (buffer.size() < total * io.GetComponentSize())
    return corrupt(path, "it holds fewer voxels than its header says");
  if (!voxelTypeOfComponent(io.GetComponentType(), type))
    return R(ErrorCode::NotALabelMap,
             quoted(path) + " has an unsupported pixel type (" +
                 itk::ImageIOBase::GetComponentTypeAsString(io.GetComponentType()) +
                 "); save the label map with integer voxels.");
  return labelsFromVoxels(buffer.data(), type, total, path);
}

/// The material table: defaults, named and coloured by the segment with the same label value.
std::vector<Material> materialsOf(const std::vector<int32_t>& present,
                                  const std::vector<SegmentInfo>& segments) {
  std::vector<Material> materials = defaultMaterials(present);
  for (Material& m : materials)
    for (const auto& s : segments)
      if (s.labelValue == m.id) {
        if (!s.name.empty()) m.name = s.name;
        if (s.hasColor) m.color = s.color;
        break;
      }
  return materials;
}

}  // namespace

Result<LabelVolume> readLabelMap(const std::string& path) {
  using R = Result<LabelVolume>;
  if (Status s = checkInputFile(path); !s) return s;
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
  const auto layout = layoutOf(*io, path);
  if (!layout) return layout.status();
  const unsigned layers = layout->layers;
  LabelVolume v = geometryOf(*io, layout->spatial0);
  v.sourcePath = path;
  if (Status s = validateLabelGeometry(v, path); !s) return s;
  // Segment names and colours: Slicer .seg.nrrd, and NRRD/MetaImage files written by FEMesher
  // (which stores its material table under the same keys).
  std::vector<SegmentInfo> segments = parseSegments(io->GetMetaDataDictionary());
  if (Status s = checkDuplicateLabelValues(path, segments); !s) return s;
  const size_t n = v.voxelCount();
  // Before allocating: reading holds the voxels as stored plus one int32 per value (and one per
  // voxel to merge .seg.nrrd layers); refuse at once what this machine cannot hold.
  const uintmax_t stored = uintmax_t(io->GetImageSizeInBytes());
  if (Status s = labelio::checkMemory(path, v.dims.data(), n, stored,
                                      stored + 4 * uintmax_t(n) * (layers + (layers > 1 ? 1 : 0)));
      !s)
    return s;
  auto values = readValues(*io, n * layers, path);
  if (!values) return values.status();
  if (layers > 1) {
    auto merged = mergeLayers(path, values.value(), n, layers, segments);
    if (!merged) return merged.status();
    v.labels = std::move(merged).value();
  } else {
    // A single layer: stored values are the LabelValues; ignore segments of other layers.
    segments.erase(std::remove_if(segments.begin(), segments.end(),
                                  [](const SegmentInfo& s) { return s.layer != 0; }),
                   segments.end());
    v.labels = std::move(values).value();
  }
  const auto present = validateLabelVolume(v, path);
  if (!present) return present.status();
  v.materials = materialsOf(present.value(), segments);
  return v;
}

}  // namespace femesher
