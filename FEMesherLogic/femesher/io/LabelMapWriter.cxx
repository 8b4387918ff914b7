// SPDX-License-Identifier: GPL-3.0-or-later
// Writing label maps and scalar volumes with ITK (declared in LabelMapIO.h).
#include <femesher/io/AtomicFile.h>
#include <femesher/io/LabelMapFiles.h>
#include <femesher/io/LabelMapIO.h>

#include <itkImage.h>
#include <itkImageFileWriter.h>
#include <itkImageIOFactory.h>
#include <itkMetaDataObject.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>

namespace femesher {

namespace fs = std::filesystem;

namespace {

using labelio::itkMessage;
using labelio::quoted;
using labelio::trim;

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

}  // namespace femesher
