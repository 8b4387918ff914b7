// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/io/AtomicFile.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <filesystem>
#include <system_error>
#include <unistd.h>

namespace femesher {

namespace fs = std::filesystem;

Status writeAtomically(const std::string& path,
                       const std::function<Status(const std::string& tmpPath)>& writer) {
  static std::atomic<unsigned> counter{0};
  const fs::path target(path);
  const fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
  std::error_code ec;
  if (!fs::is_directory(dir, ec))
    return {ErrorCode::WriteFailed, "Cannot write '" + path + "': folder '" + dir.string() +
                                        "' does not exist. Create it or choose another path."};
  // Keep the real extension last: some writers (ITK, VTK) choose the format from it.
  const std::string ext = fileExtension(path);
  std::string stem = target.filename().string();
  stem = stem.substr(0, stem.size() - ext.size());
  const fs::path tmp = dir / ("." + stem + ".tmp" + std::to_string(::getpid()) + "_" +
                              std::to_string(counter++) + ext);
  Status status;
  try {
    status = writer(tmp.string());
  } catch (const Error& e) {
    status = e.status();
  } catch (const std::exception& e) {
    status = Status(ErrorCode::WriteFailed, "Cannot write '" + path + "': " + e.what());
  }
  if (status.isOk() && !fs::exists(tmp, ec))
    status = Status(ErrorCode::WriteFailed, "Cannot write '" + path + "': the writer produced no file");
  if (!status.isOk()) {
    fs::remove(tmp, ec);
    return status;
  }
  fs::rename(tmp, target, ec);
  if (ec) {
    fs::remove(tmp, ec);
    return {ErrorCode::WriteFailed, "Cannot write '" + path + "': " + ec.message()};
  }
  return Status::ok();
}

std::string fileExtension(const std::string& path) {
  std::string name = fs::path(path).filename().string();
  std::transform(name.begin(), name.end(), name.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  for (const char* compound : {".seg.nrrd", ".nii.gz", ".vtk.gz"}) {
    const std::string c(compound);
    if (name.size() > c.size() && name.compare(name.size() - c.size(), c.size(), c) == 0) return c;
  }
  const auto dot = name.rfind('.');
  return dot == std::string::npos || dot == 0 ? std::string() : name.substr(dot);
}

}  // namespace femesher
