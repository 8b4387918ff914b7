// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/io/LabelMapFiles.h>

#include <itkMacro.h>
#include <zlib.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <vector>

namespace femesher::labelio {

namespace fs = std::filesystem;

namespace {

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

}  // namespace

std::string trim(const std::string& s) {
  const auto a = s.find_first_not_of(" \t\r\n");
  if (a == std::string::npos) return {};
  const auto b = s.find_last_not_of(" \t\r\n");
  return s.substr(a, b - a + 1);
}

std::string quoted(const std::string& path) { return "'" + path + "'"; }

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

}  // namespace femesher::labelio
