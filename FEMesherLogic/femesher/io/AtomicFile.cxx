// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/io/AtomicFile.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <filesystem>
#include <regex>
#include <set>
#include <signal.h>
#include <system_error>
#include <unistd.h>

namespace femesher {

namespace fs = std::filesystem;

namespace {

std::atomic<unsigned> gCounter{0};

fs::path folderOf(const fs::path& target) {
  return target.has_parent_path() ? target.parent_path() : fs::path(".");
}

/// ".<stem>.femesher-<kind>-<pid>-<n><ext>" next to `target` (temporaryFileOwner reads it).
fs::path siblingName(const fs::path& target, const char* kind) {
  const std::string ext = fileExtension(target.string());
  std::string stem = target.filename().string();
  stem = stem.substr(0, stem.size() - ext.size());
  return folderOf(target) / ("." + stem + ".femesher-" + kind + "-" + std::to_string(::getpid()) +
                             "-" + std::to_string(gCounter++) + ext);
}

Status canceledStatus() { return {ErrorCode::Canceled, "The run was canceled."}; }

/// `text` with every `from` replaced by `to` (messages name the target, not the temporary).
std::string replaceAll(std::string text, const std::string& from, const std::string& to) {
  if (from.empty()) return text;
  for (size_t p = text.find(from); p != std::string::npos; p = text.find(from, p + to.size()))
    text.replace(p, from.size(), to);
  return text;
}

}  // namespace

OutputTransaction::~OutputTransaction() {
  std::error_code ec;
  for (const auto& s : staged_) fs::remove(s.tmp, ec);
}

Status OutputTransaction::stage(const std::string& path, const FileWriter& writer) {
  const fs::path target(path);
  const fs::path dir = folderOf(target);
  std::error_code ec;
  Status status;
  if (!fs::is_directory(dir, ec)) {
    status = {ErrorCode::WriteFailed, "Cannot write '" + path + "': folder '" + dir.string() +
                                          "' does not exist. Create it or choose another path."};
  } else if (fs::is_directory(target, ec)) {
    status = {ErrorCode::WriteFailed, "Cannot write '" + path +
                                          "': it is a folder. Give a file name (e.g. '" +
                                          (target / "mesh.vtu").string() + "')."};
  }
  if (status.isOk() && canceled()) status = canceledStatus();
  const std::string tmp = siblingName(target, "tmp").string();
  if (status.isOk()) {
    try {
      status = writer(tmp);
    } catch (const Error& e) {
      status = e.status();
    } catch (const std::exception& e) {
      status = Status(ErrorCode::WriteFailed, "Cannot write '" + path + "': " + e.what());
    }
    if (status.isOk() && !fs::is_regular_file(tmp, ec))
      status = Status(ErrorCode::WriteFailed, "Cannot write '" + path + "': the writer produced no file.");
  }
  if (!status.isOk()) {
    fs::remove(tmp, ec);
    failed_ = true;
    return Status(status.code(), replaceAll(status.message(), tmp, path));
  }
  staged_.push_back({tmp, path});
  return Status::ok();
}

Status OutputTransaction::commit() {
  if (canceled()) return canceledStatus();
  if (failed_)
    return {ErrorCode::WriteFailed, "Not writing any output: another output of this run failed."};
  std::error_code ec;
  // Existing targets are kept under a second name (a hard link, or a copy where links are not
  // possible) until every rename succeeded, so a failed rename can put them back.
  std::vector<std::string> backups(staged_.size());
  std::vector<bool> renamed(staged_.size(), false);
  Status status;
  for (size_t i = 0; i < staged_.size() && status.isOk(); ++i) {
    const Staged& s = staged_[i];
    if (canceled()) {  // a signal before the last rename: roll back
      status = canceledStatus();
      break;
    }
    if (fs::is_regular_file(s.path, ec)) {
      const fs::path backup = siblingName(s.path, "bak");
      fs::create_hard_link(s.path, backup, ec);
      if (ec) fs::copy_file(s.path, backup, ec);
      if (ec) {
        status = {ErrorCode::WriteFailed, "Cannot replace '" + s.path + "': " + ec.message() +
                                              ". Check the folder's permissions and free space."};
        break;
      }
      backups[i] = backup.string();
    }
    fs::rename(s.tmp, s.path, ec);
    if (ec)
      status = {ErrorCode::WriteFailed, "Cannot write '" + s.path + "': " + ec.message() +
                                            ". Check the path and the folder's permissions."};
    else
      renamed[i] = true;
  }
  for (size_t i = 0; i < staged_.size(); ++i) {
    if (!status.isOk() && renamed[i]) {  // roll back: the old file, or no file
      if (!backups[i].empty()) fs::rename(backups[i], staged_[i].path, ec);
      else fs::remove(staged_[i].path, ec);
    }
    if (!backups[i].empty()) fs::remove(backups[i], ec);
  }
  if (status.isOk()) staged_.clear();  // nothing left for the destructor to remove
  return status;
}

namespace {
std::atomic<const std::atomic<bool>*> gProcessCancel{nullptr};
}  // namespace

void setProcessCancelFlag(const std::atomic<bool>* flag) { gProcessCancel = flag; }

Status writeAtomically(const std::string& path, const FileWriter& writer) {
  OutputTransaction t;
  t.setCancelFlag(gProcessCancel.load());
  if (Status s = t.stage(path, writer); !s) return s;
  return t.commit();
}

long temporaryFileOwner(const std::string& fileName) {
  static const std::regex pattern(R"(^\..+\.femesher-(tmp|bak)-([0-9]{1,9})-[0-9]+(\.[a-z0-9]+){0,2}$)");
  std::smatch m;
  if (!std::regex_match(fileName, m, pattern)) return 0;
  return std::stol(m[2].str());
}

std::vector<std::string> removeStaleTemporaries(const std::vector<std::string>& outputs) {
  std::set<fs::path> folders;
  for (const auto& o : outputs)
    if (!o.empty()) folders.insert(folderOf(fs::path(o)));
  std::vector<std::string> removed;
  for (const auto& dir : folders) {
    std::error_code ec;
    std::vector<std::pair<fs::path, long>> candidates;  // listed first, removed after
    for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
      const long pid = temporaryFileOwner(it->path().filename().string());
      std::error_code fec;
      if (pid > 0 && pid != long(::getpid()) && fs::is_regular_file(it->symlink_status(fec)))
        candidates.emplace_back(it->path(), pid);  // no links, folders, ...
    }
    for (const auto& [path, pid] : candidates) {
      if (::kill(pid_t(pid), 0) == 0 || errno != ESRCH) continue;  // alive (or not ours to see)
      if (fs::remove(path, ec)) removed.push_back(path.string());
    }
  }
  return removed;
}

Status checkDistinctOutputs(const std::vector<std::string>& paths) {
  std::vector<std::pair<fs::path, std::string>> seen;
  for (const auto& p : paths) {
    if (p.empty()) continue;
    std::error_code ec;
    fs::path canonical = fs::weakly_canonical(fs::absolute(p, ec), ec);
    if (ec) canonical = fs::absolute(p, ec).lexically_normal();
    for (const auto& [other, name] : seen)
      if (other == canonical)
        return {ErrorCode::InvalidArgument,
                "Two outputs are the same file: '" + name + "' and '" + p +
                    "'. Give each output (-o, --report, --save-parameters) its own path."};
    seen.emplace_back(canonical, p);
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
