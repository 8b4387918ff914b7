// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/io/LabelMapFiles.h>
#include <femesher/io/LabelValidation.h>

#include <itkMacro.h>
#include <zlib.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <vector>

#include <sys/resource.h>
#include <unistd.h>

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

/// Deflate expands at most 1032:1: compressed data of `bytes` cannot hold more than this.
constexpr uintmax_t kMaxDeflateRatio = 1032;

std::string gigabytes(uintmax_t bytes) {
  char text[64];
  std::snprintf(text, sizeof text, "%.1f GB", double(bytes) / 1e9);
  return text;
}

/// Bytes of one value of a NRRD `type` (every spelling of the NRRD format; 0: unknown).
uintmax_t nrrdTypeBytes(const std::string& type) {
  static const std::map<std::string, uintmax_t> bytes = {
      {"signed char", 1}, {"int8", 1}, {"int8_t", 1}, {"uchar", 1}, {"unsigned char", 1},
      {"uint8", 1}, {"uint8_t", 1}, {"short", 2}, {"short int", 2}, {"signed short", 2},
      {"signed short int", 2}, {"int16", 2}, {"int16_t", 2}, {"ushort", 2},
      {"unsigned short", 2}, {"unsigned short int", 2}, {"uint16", 2}, {"uint16_t", 2},
      {"int", 4}, {"signed int", 4}, {"int32", 4}, {"int32_t", 4}, {"uint", 4},
      {"unsigned int", 4}, {"uint32", 4}, {"uint32_t", 4}, {"longlong", 8}, {"long long", 8},
      {"long long int", 8}, {"signed long long", 8}, {"signed long long int", 8}, {"int64", 8},
      {"int64_t", 8}, {"ulonglong", 8}, {"unsigned long long", 8}, {"unsigned long long int", 8},
      {"uint64", 8}, {"uint64_t", 8}, {"float", 4}, {"double", 8}};
  const auto it = bytes.find(type);
  return it == bytes.end() ? 0 : it->second;
}

/// Inflates the gzip (or zlib) data of `in` from its current position to the end: the bytes it
/// decodes to, or an error text (zlib's: cut off, damaged, CRC-32 or length check failed).
std::string inflateAll(std::istream& in, uintmax_t& decoded) {
  z_stream z{};
  if (inflateInit2(&z, 15 + 32) != Z_OK) return "zlib could not start";
  std::vector<unsigned char> input(1 << 16), output(1 << 18);
  int rc = Z_OK;
  decoded = 0;
  bool any = false;
  while (true) {
    if (z.avail_in == 0) {
      in.read(reinterpret_cast<char*>(input.data()), std::streamsize(input.size()));
      z.avail_in = unsigned(in.gcount());
      z.next_in = input.data();
      if (z.avail_in == 0) break;
    }
    if (rc == Z_STREAM_END) {  // another gzip member follows (concatenated streams)
      if (inflateReset(&z) != Z_OK) break;
    }
    z.avail_out = unsigned(output.size());
    z.next_out = output.data();
    rc = inflate(&z, Z_NO_FLUSH);
    decoded += output.size() - z.avail_out;
    any = true;
    if (rc != Z_OK && rc != Z_STREAM_END && rc != Z_BUF_ERROR) break;
  }
  std::string error;
  if (rc != Z_OK && rc != Z_STREAM_END)
    error = std::string("its compressed data is damaged (zlib: ") +
            (z.msg ? z.msg : "invalid data") + ")";
  else if (rc != Z_STREAM_END || !any)
    error = "its compressed data is cut off (the gzip stream ends before its end marker)";
  inflateEnd(&z);
  return error;
}

/// The entries of a NRRD per-axis vector field ("(1,0,0) none (0,1,0)"): one per axis, empty
/// for "none"; `ok` false when an entry is not a list of numbers.
std::vector<std::vector<double>> nrrdVectors(const std::string& text, bool& ok) {
  std::vector<std::vector<double>> out;
  ok = true;
  size_t i = 0;
  while (i < text.size()) {
    if (std::isspace(static_cast<unsigned char>(text[i]))) {
      ++i;
      continue;
    }
    if (text[i] != '(') {  // "none" (or a word ITK will refuse itself)
      const size_t end = text.find_first_of(" \t", i);
      out.emplace_back();
      i = end == std::string::npos ? text.size() : end;
      continue;
    }
    const size_t close = text.find(')', i);
    if (close == std::string::npos) {
      ok = false;
      return out;
    }
    std::string inner = text.substr(i + 1, close - i - 1);
    std::replace(inner.begin(), inner.end(), ',', ' ');
    std::vector<double> v;
    const char* p = inner.c_str();
    while (true) {
      while (std::isspace(static_cast<unsigned char>(*p))) ++p;
      if (*p == '\0') break;
      char* end = nullptr;
      const double x = std::strtod(p, &end);
      if (end == p) {
        ok = false;
        return out;
      }
      v.push_back(x);
      p = end;
    }
    out.push_back(v);
    i = close + 1;
  }
  return out;
}

std::string vectorText(const std::vector<double>& v) {
  std::string t = "(";
  for (size_t k = 0; k < v.size(); ++k) t += (k ? ", " : "") + number(v[k]);
  return t + ")";
}

/// |det| of the 3x3 matrix with columns a, b, c, divided by the product of their lengths (1 for
/// orthogonal axes, 0 for dependent ones).
double normalizedDeterminant(const double* a, const double* b, const double* c) {
  const double det = a[0] * (b[1] * c[2] - b[2] * c[1]) - b[0] * (a[1] * c[2] - a[2] * c[1]) +
                     c[0] * (a[1] * b[2] - a[2] * b[1]);
  const double la = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
  const double lb = std::sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
  const double lc = std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
  return la > 0 && lb > 0 && lc > 0 ? std::fabs(det) / (la * lb * lc) : 0.0;
}

const char* const kAxisNames[3] = {"i", "j", "k"};

/// The geometry of a NRRD header (see checkNrrd): NaN, infinite, zero or negative spacings,
/// direction vectors that are not finite, zero or independent, an origin that is not finite.
Status checkNrrdGeometry(const std::string& path, std::map<std::string, std::string>& h) {
  const int dim = std::atoi(h["dimension"].c_str());
  if (dim < 1 || dim > 16) return Status::ok();  // ITK refuses such headers itself
  std::vector<std::string> kinds;
  {
    std::istringstream in(h["kinds"]);
    for (std::string k; in >> k;) kinds.push_back(k);
  }
  auto spatial = [&](int axis) {
    if (size_t(axis) >= kinds.size()) return true;
    const std::string& k = kinds[size_t(axis)];
    return k == "domain" || k == "space" || k == "time" || k == "???";
  };
  std::vector<int> spatialAxes;
  for (int a = 0; a < dim; ++a)
    if (spatial(a)) spatialAxes.push_back(a);
  auto axisName = [&](int axis) {
    const auto it = std::find(spatialAxes.begin(), spatialAxes.end(), axis);
    const size_t s = size_t(it - spatialAxes.begin());
    return (s < 3 ? std::string(kAxisNames[s]) + " (axis " : "(axis ") + std::to_string(axis) + ")";
  };
  if (!h["spacings"].empty()) {
    std::istringstream in(h["spacings"]);
    std::string word;
    for (int a = 0; a < dim && in >> word; ++a) {
      if (!spatial(a)) continue;
      char* end = nullptr;
      const double x = std::strtod(word.c_str(), &end);
      if (*end != '\0') continue;  // not a number: ITK's own message
      if (!(x > 0) || !std::isfinite(x))
        return badGeometry(path, "`spacings` value along " + axisName(a), "'" + word + "'",
                           std::isfinite(x) ? "a voxel size must be greater than 0"
                                            : "a voxel size must be a finite number");
    }
  }
  if (!h["spacedirections"].empty()) {
    bool ok = true;
    const auto dirs = nrrdVectors(h["spacedirections"], ok);
    std::vector<const std::vector<double>*> columns;
    for (int a = 0; ok && a < dim && size_t(a) < dirs.size(); ++a) {
      const std::vector<double>& d = dirs[size_t(a)];
      if (d.empty() || !spatial(a)) continue;
      double length = 0;
      for (double x : d) {
        if (!std::isfinite(x))
          return badGeometry(path, "`space directions` vector of " + axisName(a), vectorText(d),
                             "its entries must be finite numbers");
        length += x * x;
      }
      if (!(length > 0))
        return badGeometry(path, "`space directions` vector of " + axisName(a), vectorText(d),
                           "a zero vector gives voxels of size 0");
      columns.push_back(&d);
    }
    if (ok && columns.size() == 3 && columns[0]->size() == 3 && columns[1]->size() == 3 &&
        columns[2]->size() == 3 &&
        normalizedDeterminant(columns[0]->data(), columns[1]->data(), columns[2]->data()) < 1e-6)
      return badGeometry(path, "`space directions`", "'" + h["spacedirections"] + "'",
                         "the three axes are not independent, so voxels have no volume");
  }
  if (!h["spaceorigin"].empty()) {
    bool ok = true;
    const auto origin = nrrdVectors(h["spaceorigin"], ok);
    if (ok && !origin.empty())
      for (double x : origin.front())
        if (!std::isfinite(x))
          return badGeometry(path, "`space origin`", vectorText(origin.front()),
                             "a position must be a finite number");
  }
  return Status::ok();
}

/// The geometry fields of a NIfTI-1 or NIfTI-2 header.
struct NiftiGeometry {
  int nd = 0;
  double pixdim[8] = {};
  int qformCode = 0, sformCode = 0;
  double quatern[6] = {};  ///< quatern_b, _c, _d, qoffset_x, _y, _z
  double srow[12] = {};    ///< srow_x, srow_y, srow_z
};

/// See checkNifti: ITK reads a NaN, infinite or zero pixdim as 1 mm without a word.
Status checkNiftiGeometry(const std::string& path, const NiftiGeometry& g) {
  for (int k = 1; k <= std::min(g.nd, 3); ++k)
    if (!(g.pixdim[k] > 0) || !std::isfinite(g.pixdim[k]))
      return badGeometry(path, "pixdim[" + std::to_string(k) + "] (the voxel size along " +
                                   kAxisNames[k - 1] + ")",
                         number(g.pixdim[k]),
                         std::isfinite(g.pixdim[k]) ? "a voxel size must be greater than 0"
                                                    : "a voxel size must be a finite number");
  static const char* const quaternNames[6] = {"quatern_b", "quatern_c", "quatern_d",
                                              "qoffset_x", "qoffset_y", "qoffset_z"};
  const std::string farAway = "the origin must lie within " + number(kMaxCoordinate) + " mm of 0";
  // ITK reads the qform and sform in float precision: an origin too far for the voxel size makes
  // it refuse the direction cosines with a message of its own, so the same check as
  // validateLabelGeometry is made here.
  const double minSpacing = std::min({g.pixdim[1], g.pixdim[2], g.pixdim[3]});
  auto imprecise = [&](const char* field, double offset) {
    return badGeometry(path, field, number(offset) + " mm",
                       "so far from 0 that voxel positions lose their precision for voxels of " +
                           number(minSpacing) + " mm");
  };
  if (g.qformCode > 0)
    for (int k = 0; k < 6; ++k) {
      if (!std::isfinite(g.quatern[k]))
        return badGeometry(path, std::string(quaternNames[k]) + " (of the qform)",
                           number(g.quatern[k]), "it must be a finite number");
      if (k >= 3 && std::fabs(g.quatern[k]) > kMaxCoordinate)
        return badGeometry(path, std::string(quaternNames[k]) + " (of the qform)",
                           number(g.quatern[k]) + " mm", farAway);
      if (k >= 3 && !coordinatesExact(std::fabs(g.quatern[k]), minSpacing))
        return imprecise((std::string(quaternNames[k]) + " (of the qform's origin)").c_str(),
                         g.quatern[k]);
    }
  if (g.sformCode > 0) {
    static const char* const rowNames[3] = {"srow_x", "srow_y", "srow_z"};
    for (int k = 0; k < 12; ++k)
      if (!std::isfinite(g.srow[k]))
        return badGeometry(path, std::string(rowNames[k / 4]) + " (of the sform)",
                           vectorText({g.srow[4 * (k / 4)], g.srow[4 * (k / 4) + 1],
                                       g.srow[4 * (k / 4) + 2], g.srow[4 * (k / 4) + 3]}),
                           "its entries must be finite numbers");
    for (int r = 0; r < 3; ++r) {
      const std::string field = std::string(rowNames[r]) + "[3] (the sform's origin)";
      if (std::fabs(g.srow[4 * r + 3]) > kMaxCoordinate)
        return badGeometry(path, field, number(g.srow[4 * r + 3]) + " mm", farAway);
      if (!coordinatesExact(std::fabs(g.srow[4 * r + 3]), minSpacing))
        return imprecise(field.c_str(), g.srow[4 * r + 3]);
    }
    const double a[3] = {g.srow[0], g.srow[4], g.srow[8]}, b[3] = {g.srow[1], g.srow[5], g.srow[9]},
                 c[3] = {g.srow[2], g.srow[6], g.srow[10]};
    if (normalizedDeterminant(a, b, c) < 1e-6)
      return badGeometry(path, "sform (srow_x, srow_y, srow_z)",
                         vectorText({g.srow[0], g.srow[1], g.srow[2], g.srow[3]}) + ", " +
                             vectorText({g.srow[4], g.srow[5], g.srow[6], g.srow[7]}) + ", " +
                             vectorText({g.srow[8], g.srow[9], g.srow[10], g.srow[11]}),
                         "its three axes are not independent, so voxels have no volume");
  }
  return Status::ok();
}

}  // namespace

std::string number(double x) {
  if (std::isnan(x)) return "nan";
  if (std::isinf(x)) return x > 0 ? "inf" : "-inf";
  char text[40];
  for (int precision = 1; precision <= 17; ++precision) {
    std::snprintf(text, sizeof text, "%.*g", precision, x);
    if (std::strtod(text, nullptr) == x) break;
  }
  return text;
}

Status badGeometry(const std::string& path, const std::string& field, const std::string& value,
                   const std::string& why) {
  return {ErrorCode::CorruptFile,
          quoted(path) + " has an invalid header: its " + field + " is " + value + " (" + why +
              "). Fix the header (e.g. in 3D Slicer: Volumes module > Volume Information, then "
              "save the label map again) and check its geometry with `femesher info`."};
}

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
  // Geometry ITK's MetaIO cannot parse (NaN, infinities: it fails with an unrelated message).
  for (const char* key : {"ElementSpacing", "Offset", "Origin", "Position", "TransformMatrix",
                          "Rotation", "Orientation"}) {
    const auto it = h.find(key);
    if (it == h.end()) continue;
    std::istringstream in(it->second);
    for (std::string word; in >> word;) {
      char* end = nullptr;
      const double x = std::strtod(word.c_str(), &end);
      if (*end != '\0') break;  // not a number: MetaIO's own message
      if (!std::isfinite(x))
        return badGeometry(path, "`" + std::string(key) + "`", "'" + it->second + "'",
                           "its values must be finite numbers");
    }
  }
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
  auto f64 = [&](size_t off, bool swap) { double x; std::memcpy(&x, get(off, 8, swap).data(), 8); return x; };
  uintmax_t voxels = 1, bitpix = 0, offset = 0;
  NiftiGeometry g;
  if (sizeofHdr == 348) {
    const int nd = i16(40, swap);
    if (nd < 1 || nd > 7) return Status::ok();
    g.nd = nd;
    for (int k = 0; k < 8; ++k) g.pixdim[k] = f32(76 + 4 * size_t(k), swap);
    g.qformCode = i16(252, swap);
    g.sformCode = i16(254, swap);
    for (int k = 0; k < 6; ++k) g.quatern[k] = f32(256 + 4 * size_t(k), swap);
    for (int k = 0; k < 12; ++k) g.srow[k] = f32(280 + 4 * size_t(k), swap);
    for (int d = 1; d <= nd; ++d) voxels *= uintmax_t(std::max<int16_t>(1, i16(40 + 2 * size_t(d), swap)));
    bitpix = uintmax_t(std::max<int16_t>(0, i16(72, swap)));
    offset = uintmax_t(std::max(0.f, f32(108, swap)));
    if (offset == 0) return checkNiftiGeometry(path, g);  // a .hdr/.img pair: data elsewhere
  } else if (sizeofHdr == 540 && got == 540) {
    const int64_t nd = i64(16, swap);
    if (nd < 1 || nd > 7) return Status::ok();
    g.nd = int(nd);
    for (int k = 0; k < 8; ++k) g.pixdim[k] = f64(104 + 8 * size_t(k), swap);
    g.qformCode = i32(344, swap);
    g.sformCode = i32(348, swap);
    for (int k = 0; k < 6; ++k) g.quatern[k] = f64(352 + 8 * size_t(k), swap);
    for (int k = 0; k < 12; ++k) g.srow[k] = f64(400 + 8 * size_t(k), swap);
    for (int d = 1; d <= nd; ++d) voxels *= uintmax_t(std::max<int64_t>(1, i64(16 + 8 * size_t(d), swap)));
    bitpix = uintmax_t(std::max<int16_t>(0, i16(14, swap)));
    offset = uintmax_t(std::max<int64_t>(0, i64(168, swap)));
  } else {
    return Status::ok();  // not NIfTI: ITK decides
  }
  if (Status s = checkNiftiGeometry(path, g); !s) return s;
  const uintmax_t expected = offset + voxels * bitpix / 8;
  std::error_code ec;
  const uintmax_t fileBytes = fs::file_size(path, ec);
  if (!ec && expected > fileBytes * kMaxDeflateRatio + 4096)
    return corrupt(path, "its header describes " + std::to_string(expected) +
                             " bytes but the file holds only " + std::to_string(fileBytes) +
                             ", too few even compressed (truncated, or a header that lies)");
  // Read to the end, so that zlib checks the gzip trailer (CRC-32 and length) too.
  uintmax_t available = uintmax_t(got);
  std::vector<char> chunk(1 << 18);
  while (true) {
    const int n = gzread(f, chunk.data(), unsigned(chunk.size()));
    if (n <= 0) break;
    available += uintmax_t(n);
  }
  int err = Z_OK;
  const char* message = gzerror(f, &err);
  if (err != Z_OK && err != Z_STREAM_END)
    return corrupt(path, std::string("its compressed data is cut off or damaged (zlib: ") + message +
                             "); a reader would mesh wrong or missing voxels");
  if (available < expected)
    return corrupt(path, "its header describes " + std::to_string(expected) + " bytes but the file holds only " +
                             std::to_string(available) + " (truncated); a reader would fill the rest with 0");
  return Status::ok();
}

Status checkNrrd(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::string line;
  if (!std::getline(in, line) || line.rfind("NRRD", 0) != 0) return Status::ok();
  std::map<std::string, std::string> h;
  bool attached = false;
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty()) {
      attached = true;  // the data follows the blank line
      break;
    }
    if (line[0] == '#' || line.find(":=") != std::string::npos) continue;
    const auto colon = line.find(": ");
    if (colon == std::string::npos) continue;
    std::string key = line.substr(0, colon);
    key.erase(std::remove(key.begin(), key.end(), ' '), key.end());  // "data file" = "datafile"
    h[key] = trim(line.substr(colon + 2));
  }
  if (Status s = checkNrrdGeometry(path, h); !s) return s;
  const uintmax_t typeBytes = nrrdTypeBytes(h["type"]);
  if (typeBytes == 0 || h["sizes"].empty()) return Status::ok();
  std::istringstream sizes(h["sizes"]);
  uintmax_t claimed = typeBytes, d = 0;
  std::string sizesText;
  while (sizes >> d) {
    if (d != 0 && claimed > UINTMAX_MAX / d) return Status::ok();  // ITK refuses such sizes
    claimed *= d;
    sizesText += (sizesText.empty() ? "" : " x ") + std::to_string(d);
  }
  const std::string encoding = h["encoding"];
  if (encoding == "bzip2" || encoding == "bz2")  // NrrdIO (ITK's NRRD reader) has no bzip2
    return {ErrorCode::UnreadableFile,
            quoted(path) + " holds bzip2-compressed NRRD data, which FEMesher's NRRD reader (ITK's "
                           "NrrdIO) cannot decode; the file is not damaged. Save it again with gzip "
                           "or raw encoding (e.g. `unu save -e gzip`, or 3D Slicer's .nrrd)."};
  const bool gz = encoding == "gzip" || encoding == "gz";
  if (encoding != "raw" && !gz) return Status::ok();
  // Where the data is: after the header, or in one data file (lists and patterns: ITK's part).
  std::string dataName = "the data after its header";
  const std::string dataFile = h.count("datafile") ? h["datafile"] : h["data_file"];
  if (!dataFile.empty()) {
    if (dataFile.rfind("LIST", 0) == 0 || dataFile.find(' ') != std::string::npos) return Status::ok();
    fs::path p(dataFile);
    if (p.is_relative()) p = fs::path(path).parent_path() / p;
    in = std::ifstream(p, std::ios::binary);
    if (!in)
      return {ErrorCode::CorruptFile,
              quoted(path) + " refers to the data file '" + p.string() +
                  "', which is missing or unreadable. Keep the .nhdr and its data file together in "
                  "one folder (or convert to a single .nrrd file)."};
    dataName = "'" + p.filename().string() + "'";
  } else if (!attached) {
    return corrupt(path, "its header ends without data (no blank line, no data file)");
  }
  const long lineSkip = std::atol((h.count("lineskip") ? h["lineskip"] : h["line_skip"]).c_str());
  for (long i = 0; i < lineSkip && std::getline(in, line); ++i) {}
  const long byteSkip = std::atol((h.count("byteskip") ? h["byteskip"] : h["byte_skip"]).c_str());
  const std::streamoff start = in.tellg();
  in.seekg(0, std::ios::end);
  const uintmax_t present = start < 0 ? 0 : uintmax_t(in.tellg() - start);
  in.seekg(start);
  const std::string claim = "its header describes " + sizesText + " values of " +
                            std::to_string(typeBytes) + " byte(s), " + std::to_string(claimed) +
                            " bytes of voxels, but " + dataName + " holds only ";
  if (!gz) {
    const uintmax_t skip = byteSkip > 0 ? uintmax_t(byteSkip) : 0;
    if (byteSkip >= 0 && present < claimed + skip)
      return corrupt(path, claim + std::to_string(present > skip ? present - skip : 0) +
                               " bytes (truncated, or a header that lies)");
    return Status::ok();
  }
  if (claimed > present * kMaxDeflateRatio + 4096)
    return corrupt(path, claim + std::to_string(present) +
                             " compressed bytes, which cannot decode to that many (truncated, or a "
                             "header that lies)");
  uintmax_t decoded = 0;
  if (std::string error = inflateAll(in, decoded); !error.empty())
    return corrupt(path, error + "; a reader would mesh wrong or missing voxels");
  const uintmax_t skip = byteSkip > 0 ? uintmax_t(byteSkip) : 0;
  if (decoded < claimed + skip)
    return corrupt(path, claim + std::to_string(decoded) + " bytes once decompressed (truncated)");
  return Status::ok();
}

uintmax_t availableMemory() {
  uintmax_t available = 0;
  std::ifstream meminfo("/proc/meminfo");
  std::string key;
  uintmax_t kb = 0;
  std::string unit;
  while (meminfo >> key >> kb >> unit)
    if (key == "MemAvailable:") {
      available = kb * 1024;
      break;
    }
  if (available == 0) {
    const long pages = ::sysconf(_SC_AVPHYS_PAGES), page = ::sysconf(_SC_PAGESIZE);
    if (pages > 0 && page > 0) available = uintmax_t(pages) * uintmax_t(page);
  }
  struct rlimit limit {};
  if (::getrlimit(RLIMIT_AS, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY) {
    const uintmax_t cap = uintmax_t(limit.rlim_cur);
    available = available == 0 ? cap : std::min(available, cap);
  }
  return available;
}

Status checkMemory(const std::string& path, const int dims[3], uintmax_t voxels,
                   uintmax_t storedBytes, uintmax_t bytesNeeded) {
  const uintmax_t available = availableMemory();
  if (available == 0 || bytesNeeded <= available) return Status::ok();
  return {ErrorCode::UnreadableFile,
          quoted(path) + " is too large for the memory available: " + std::to_string(dims[0]) +
              " x " + std::to_string(dims[1]) + " x " + std::to_string(dims[2]) + " = " +
              std::to_string(voxels) + " voxels (" + std::to_string(storedBytes) +
              " bytes as stored); reading it needs at least " + std::to_string(bytesNeeded) +
              " bytes (" + gigabytes(bytesNeeded) + ") but only " + std::to_string(available) +
              " bytes (" + gigabytes(available) +
              ") are available. Crop the label map to the labelled region or resample it to "
              "larger voxels (e.g. 3D Slicer's Crop Volume), or run on a machine with more memory."};
}

}  // namespace femesher::labelio
