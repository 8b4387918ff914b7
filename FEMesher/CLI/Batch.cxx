// SPDX-License-Identifier: GPL-3.0-or-later
// `femesher batch`: every case is a child process `femesher mesh` (a crash in one case cannot
// take down the others), started by this process, which only schedules, records and summarises.
#include "Batch.h"

#include "CliCommon.h"
#include "CohortSummary.h"

#include <femesher/Status.h>
#include <femesher/Version.h>
#include <femesher/io/AtomicFile.h>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <fcntl.h>
#include <glob.h>
#include <sched.h>
#include <sys/prctl.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <thread>

namespace femesher::cli {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

volatile std::sig_atomic_t gBatchSignal = 0;

void onBatchSignal(int sig) { gBatchSignal = sig; }

/// One case of the cohort.
struct Case {
  std::string id, input, parameterFile, labelNames;
  std::string dir;                      ///< OUT/<id>
  std::vector<std::string> args;        ///< femesher mesh's arguments, without --threads
  std::vector<std::string> settings;    ///< formats, --preset and --set: part of the fingerprint
  json fingerprint;                     ///< what resume compares (see caseFingerprint)
  uintmax_t perProcessBytes = 0;        ///< memory estimate per process (see memoryEstimateJson)
  size_t materials = 0;
  double startedUnix = 0;               ///< when its last child started (seconds since 1970)
  CaseRecord record;
};

/// The CPUs this process may run on (taskset, cgroup cpusets), at least 1.
int usableCores() {
  cpu_set_t set;
  if (sched_getaffinity(0, sizeof set, &set) == 0) return std::max(1, CPU_COUNT(&set));
  return std::max(1u, std::thread::hardware_concurrency());
}

bool endsWith(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}

std::string lower(std::string s) {
  for (auto& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

const char* kLabelMapExtensions[] = {".seg.nrrd", ".nii.gz", ".nrrd", ".nhdr", ".nii", ".mha", ".mhd"};

bool isLabelMapName(const std::string& name) {
  for (const char* e : kLabelMapExtensions)
    if (endsWith(lower(name), e)) return true;
  return false;
}

/// The case id of a label map: its file name without the label map extension, with every
/// character but letters, digits, '.', '_' and '-' replaced by '_' (it names a folder).
std::string caseIdOf(const std::string& path) {
  std::string name = fs::path(path).filename().string();
  for (const char* e : kLabelMapExtensions)
    if (endsWith(lower(name), e)) {
      name.resize(name.size() - std::strlen(e));
      break;
    }
  return name;
}

Status checkCaseId(const std::string& id, const std::string& where) {
  if (id.empty() || id == "." || id == ".." || id[0] == '.' ||
      id.find_first_not_of("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789._-") !=
          std::string::npos)
    return {ErrorCode::InvalidArgument,
            where + ": case id '" + id + "' cannot name a folder: use letters, digits, '.', '_' "
            "and '-' (not first '.'), e.g. through a manifest's 'case' column."};
  return Status::ok();
}

/// Splits one CSV line (RFC 4180 quotes, no line breaks inside fields).
std::vector<std::string> csvFields(const std::string& line) {
  std::vector<std::string> f(1);
  bool quoted = false;
  for (size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (quoted) {
      if (c == '"' && i + 1 < line.size() && line[i + 1] == '"') f.back() += '"', ++i;
      else if (c == '"') quoted = false;
      else f.back() += c;
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      f.emplace_back();
    } else if (c != '\r') {
      f.back() += c;
    }
  }
  for (auto& x : f) {
    const auto a = x.find_first_not_of(" \t"), b = x.find_last_not_of(" \t");
    x = a == std::string::npos ? "" : x.substr(a, b - a + 1);
  }
  return f;
}

/// A manifest: a header line naming the columns (case, label_map, parameters, label_names; the
/// first two required, any order), one case a line; '#' lines and blank lines are skipped;
/// relative paths are relative to the manifest's folder.
Status readManifest(const std::string& path, std::vector<Case>& cases) {
  std::ifstream in(path);
  if (!in) return {ErrorCode::FileNotFound, "Cannot read the manifest '" + path + "'."};
  const fs::path base = fs::path(path).parent_path();
  auto resolve = [&](const std::string& p) {
    return p.empty() || fs::path(p).is_absolute() ? p : (base / p).lexically_normal().string();
  };
  std::string line;
  std::map<std::string, size_t> col;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    if (line.find_first_not_of(" \t\r") == std::string::npos || line[0] == '#') continue;
    const auto f = csvFields(line);
    const std::string where = path + " line " + std::to_string(number);
    if (col.empty()) {
      for (size_t i = 0; i < f.size(); ++i) {
        static const std::set<std::string> known = {"case", "label_map", "parameters", "label_names"};
        if (!known.count(f[i]))
          return {ErrorCode::InvalidArgument,
                  where + ": unknown column '" + f[i] +
                      "'. A manifest's header names its columns: case, label_map (required), "
                      "parameters, label_names (optional)."};
        col[f[i]] = i;
      }
      if (!col.count("case") || !col.count("label_map"))
        return {ErrorCode::InvalidArgument,
                where + ": the header must name the columns 'case' and 'label_map'."};
      continue;
    }
    auto field = [&](const char* name) {
      const auto c = col.find(name);
      return c == col.end() || c->second >= f.size() ? std::string() : f[c->second];
    };
    Case c;
    c.id = field("case");
    c.input = resolve(field("label_map"));
    c.parameterFile = resolve(field("parameters"));
    c.labelNames = resolve(field("label_names"));
    if (c.input.empty())
      return {ErrorCode::InvalidArgument, where + ": no label_map for case '" + c.id + "'."};
    if (Status s = checkCaseId(c.id, where); !s) return s;
    cases.push_back(c);
  }
  if (col.empty()) return {ErrorCode::InvalidArgument, "The manifest '" + path + "' is empty."};
  return Status::ok();
}

/// The cases named by the inputs: CSV manifests, folders (their label maps, not subfolders),
/// glob patterns and label map files.
Status collectCases(const std::vector<std::string>& inputs, std::vector<Case>& cases) {
  for (const auto& in : inputs) {
    std::vector<std::string> files;
    if (endsWith(lower(in), ".csv")) {
      if (Status s = readManifest(in, cases); !s) return s;
      continue;
    }
    if (fs::is_directory(in)) {
      for (const auto& e : fs::directory_iterator(in))
        if (e.is_regular_file() && isLabelMapName(e.path().filename().string()))
          files.push_back(e.path().string());
    } else if (in.find_first_of("*?[") != std::string::npos) {
      glob_t g{};
      if (::glob(in.c_str(), 0, nullptr, &g) == 0)
        for (size_t i = 0; i < g.gl_pathc; ++i)
          if (fs::is_regular_file(g.gl_pathv[i])) files.push_back(g.gl_pathv[i]);
      globfree(&g);
      if (files.empty())
        return {ErrorCode::FileNotFound, "No file matches '" + in + "'."};
    } else if (fs::exists(in)) {
      files.push_back(in);
    } else {
      return {ErrorCode::FileNotFound, "Input '" + in + "' does not exist (give label maps, "
                                       "folders, glob patterns or a CSV manifest)."};
    }
    std::sort(files.begin(), files.end());
    for (const auto& f : files) {
      Case c;
      c.id = caseIdOf(f);
      c.input = f;
      if (Status s = checkCaseId(c.id, f); !s) return s;
      cases.push_back(c);
    }
  }
  std::map<std::string, std::string> seen;
  for (const auto& c : cases) {
    const auto [it, fresh] = seen.emplace(c.id, c.input);
    if (!fresh)
      return {ErrorCode::InvalidArgument,
              "Two cases are called '" + c.id + "' ('" + it->second + "' and '" + c.input +
                  "'): each case gets the folder of its name. Give them distinct ids in a CSV "
                  "manifest."};
  }
  if (cases.empty()) return {ErrorCode::FileNotFound, "No label map found in the inputs."};
  return Status::ok();
}

/// FNV-1a 64 of a file's bytes, as hex ("" when there is no file).
std::string fileHash(const std::string& path) {
  if (path.empty()) return "";
  std::ifstream in(path, std::ios::binary);
  if (!in) return "unreadable";
  uint64_t h = 1469598103934665603ull;
  char buf[65536];
  while (in.read(buf, sizeof buf) || in.gcount() > 0) {
    for (std::streamsize i = 0; i < in.gcount(); ++i) {
      h ^= static_cast<unsigned char>(buf[i]);
      h *= 1099511628211ull;
    }
  }
  char s[24];
  std::snprintf(s, sizeof s, "%016llx", static_cast<unsigned long long>(h));
  return s;
}

/// What must not have changed for a case to be skipped: the input's size and modification time,
/// the settings (formats, preset, --set), the parameter file's and colour table's contents and
/// the femesher version. Paths of outputs, parameter file and colour table are not part of it (a
/// moved output folder still resumes), nor is the thread count.
json caseFingerprint(const Case& c) {
  struct stat st {};
  const bool ok = ::stat(c.input.c_str(), &st) == 0;
  return {{"input", fs::absolute(c.input).lexically_normal().string()},
          {"input_size", ok ? json(st.st_size) : json()},
          {"input_mtime_ns",
           ok ? json(int64_t(st.st_mtim.tv_sec) * 1000000000 + st.st_mtim.tv_nsec) : json()},
          {"settings", c.settings},
          {"parameter_file_hash", fileHash(c.parameterFile)},
          {"label_names_hash", fileHash(c.labelNames)},
          {"femesher_version", FEMESHER_VERSION}};
}

std::vector<std::string> caseOutputs(const Case& c, const std::vector<std::string>& formats) {
  std::vector<std::string> out;
  for (const auto& f : formats) out.push_back((fs::path(c.dir) / (c.id + "." + f)).string());
  out.push_back((fs::path(c.dir) / kCaseReport).string());
  out.push_back((fs::path(c.dir) / "parameters.json").string());
  return out;
}

/// True when the case finished before with these very inputs and every output is there.
bool upToDate(const Case& c, const std::vector<std::string>& formats) {
  std::ifstream in(fs::path(c.dir) / kCaseRecord);
  if (!in) return false;
  json rec;
  try {
    rec = json::parse(in);
  } catch (const std::exception&) {
    return false;
  }
  if (rec.value("exit_code", -1) != 0 || rec.value("fingerprint", json()) != c.fingerprint)
    return false;
  for (const auto& o : caseOutputs(c, formats))
    if (!fs::is_regular_file(o) || fs::file_size(o) == 0) return false;
  return true;
}

std::string selfPath() {
  std::error_code ec;
  const fs::path p = fs::read_symlink("/proc/self/exe", ec);
  return ec ? std::string("femesher") : p.string();
}

/// Starts `femesher ARGS` in its own process group (a terminal's Ctrl-C reaches only the batch,
/// which forwards it once), dying with the batch (PR_SET_PDEATHSIG), stdin from /dev/null,
/// stderr appended to `log` and stdout to `stdoutFd` (or to the log when -1).
pid_t spawn(const std::vector<std::string>& args, const std::string& log, int stdoutFd) {
  const std::string exe = selfPath();
  const pid_t parent = ::getpid();
  const pid_t pid = ::fork();
  if (pid != 0) return pid;
  ::setpgid(0, 0);
  ::prctl(PR_SET_PDEATHSIG, SIGTERM);
  if (::getppid() != parent) ::_exit(12);  // the batch died between fork and prctl
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
  const int devnull = ::open("/dev/null", O_RDONLY);
  const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
  if (devnull >= 0) ::dup2(devnull, 0);
  if (fd >= 0) ::dup2(fd, 2);
  ::dup2(stdoutFd >= 0 ? stdoutFd : 2, 1);
  std::vector<char*> argv;
  argv.push_back(const_cast<char*>(exe.c_str()));
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  ::execv(exe.c_str(), argv.data());
  std::fprintf(stderr, "error: cannot run %s: %s\n", exe.c_str(), std::strerror(errno));
  ::_exit(127);
}

int exitCodeOf(int status) {
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  if (WIFSIGNALED(status)) return 128 + WTERMSIG(status);
  return 13;
}

double secondsSince(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

double unixNow() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

/// A started child: what it runs for and when it started.
struct Running {
  size_t index;
  std::chrono::steady_clock::time_point start;
  int stdoutFd = -1;   ///< read end of the estimate's stdout pipe
  uintmax_t bytes = 0; ///< memory booked for it
};

/// Forwards a received SIGINT/SIGTERM to every child once.
void forwardSignal(const std::map<pid_t, Running>& running, bool& forwarded) {
  if (!gBatchSignal || forwarded) return;
  forwarded = true;
  std::fprintf(stderr, "batch: %s received: stopping %zu running case(s); no new case starts\n",
               gBatchSignal == SIGINT ? "SIGINT" : "SIGTERM", running.size());
  for (const auto& [pid, r] : running) ::kill(pid, gBatchSignal);
}

/// Reaps one finished child, sleeping a little when none has finished; -1 when none.
pid_t reap(int& status) {
  const pid_t pid = ::waitpid(-1, &status, WNOHANG);
  if (pid > 0) return pid;
  ::usleep(50000);  // a signal cuts it short
  return -1;
}

std::string readAll(int fd) {
  std::string s;
  char buf[4096];
  ssize_t n;
  while ((n = ::read(fd, buf, sizeof buf)) > 0) s.append(buf, size_t(n));
  return s;
}

/// Phase 1: the memory estimate of every case to mesh (`femesher mesh IN --memory-estimate`),
/// `slots` at a time. A case whose estimate fails (an unreadable or corrupt label map) is a
/// failed case: its exit code and the end of its log are its record.
void estimateCases(std::vector<Case>& cases, const std::vector<size_t>& todo, int slots,
                   int threads) {
  std::map<pid_t, Running> running;
  size_t next = 0;
  bool forwarded = false;
  while (next < todo.size() || !running.empty()) {
    forwardSignal(running, forwarded);
    while (!gBatchSignal && next < todo.size() && int(running.size()) < slots) {
      Case& c = cases[todo[next]];
      int fds[2];
      if (::pipe(fds) != 0) break;
      std::vector<std::string> args = c.args;
      args.insert(args.end(), {"--threads", std::to_string(threads), "--memory-estimate"});
      const pid_t pid = spawn(args, (fs::path(c.dir) / kCaseLog).string(), fds[1]);
      ::close(fds[1]);
      running[pid] = {todo[next], std::chrono::steady_clock::now(), fds[0], 0};
      cases[todo[next++]].startedUnix = unixNow();
      // The estimate's JSON is small (far below a pipe's buffer): read once the child ended.
    }
    int status = 0;
    const pid_t pid = reap(status);
    if (pid <= 0 || !running.count(pid)) continue;
    const Running r = running[pid];
    running.erase(pid);
    const std::string out = readAll(r.stdoutFd);
    ::close(r.stdoutFd);
    Case& c = cases[r.index];
    const int code = exitCodeOf(status);
    json e;
    try {
      if (code == 0) e = json::parse(out);
    } catch (const std::exception&) {
    }
    if (code == 0 && e.is_object()) {
      c.perProcessBytes = e.value("per_process_bytes", uintmax_t(0));
      c.materials = e.value("materials", size_t(0));
      continue;
    }
    if (gBatchSignal) {  // stopped by the forwarded signal: not run, nothing to report
      c.record.status = "not_run";
      continue;
    }
    c.record.exitCode = code == 0 ? 13 : code;
    c.record.status = "failed";
    c.record.run = "meshed";
    c.record.wallSeconds = secondsSince(r.start);
    c.record.error = errorOf((fs::path(c.dir) / kCaseLog).string());
  }
  // Cases never estimated (canceled before their turn) are not run.
  for (size_t i = next; i < todo.size(); ++i) cases[todo[i]].record.status = "not_run";
}

uintmax_t peakFor(const Case& c, int threads) {
  return treePeakBytes(c.perProcessBytes, std::min<size_t>(size_t(threads), c.materials));
}

Status writeRecord(const Case& c) {
  json rec = {{"case", c.id},
              {"input", c.input},
              {"exit_code", c.record.exitCode},
              {"wall_seconds", c.record.wallSeconds},
              {"started_unix", c.startedUnix},
              {"finished_unix", c.startedUnix + c.record.wallSeconds},
              {"error", c.record.error},
              {"fingerprint", c.fingerprint}};
  const std::string path = (fs::path(c.dir) / kCaseRecord).string();
  const std::string text = rec.dump(1) + "\n";
  return writeAtomically(path, [path, text](const std::string& tmp) {
    std::ofstream out(tmp);
    out << text;
    out.close();
    return out ? Status::ok() : Status(ErrorCode::WriteFailed, "Cannot write '" + path + "'.");
  });
}

}  // namespace

std::string memoryEstimateJson(const std::string& input, const MemoryEstimate& e, int threads) {
  const uintmax_t perProcess = e.mainBytes;  // the main process's: the tree's at other thread counts
  const double requestMb = std::ceil(double(e.peakBytes) * kMemoryEstimateFactor / 1e6);
  return json({{"input", input},
               {"threads", threads},
               {"materials", e.materials},
               {"working_voxels", e.gridVoxels},
               {"interface_faces", e.interfaceFaces},
               {"peak_bytes", e.peakBytes},
               {"per_process_bytes", perProcess},
               {"request_mem_mb", uintmax_t(requestMb)},
               {"estimate_factor", kMemoryEstimateFactor},
               {"estimated_seconds", e.seconds},
               {"request_runtime_min",
                uintmax_t(std::ceil(std::max(kRuntimeRequestMinimumMinutes,
                                             kRuntimeRequestFactor * e.seconds / 60)))},
               {"available_bytes", e.availableBytes},
               {"available_source", e.availableSource}})
             .dump(1) +
         "\n";
}

CLI::App* addBatchCommand(CLI::App& app, BatchOptions& o) {
  auto* cmd = app.add_subcommand(
      "batch", "Mesh a cohort: label maps in folders, glob patterns or a CSV manifest, each case "
               "a child process of `femesher mesh`, with resume and a cohort summary");
  cmd->add_option("inputs", o.inputs,
                  "Label maps, folders (their label maps), glob patterns ('scans/*.nii.gz') or a "
                  "CSV manifest (columns case,label_map[,parameters][,label_names])");
  cmd->add_option("-o,--output-dir", o.outDir, "Output folder: one subfolder per case and the "
                                               "summary (summary.csv, .json, .html)");
  cmd->add_option("--format", o.formats, "Mesh formats, repeatable or comma-separated: vtu vtk "
                                         "inp msh mesh feb stl (default vtu)")
      ->delimiter(',');
  cmd->add_option("--jobs", o.jobs, "Cases meshed at once (default: the cores, fewer when the "
                                    "memory estimates do not fit)");
  cmd->add_option("--threads", o.threads, "Threads per case (default: cores / jobs)");
  cmd->add_option("--preset", o.preset, "Parameter preset for every case");
  cmd->add_option("--parameters", o.parameterFile,
                  "JSON parameter file for every case without its own (manifest column)");
  cmd->add_option("--set", o.sets, "Set a parameter for every case: key=value (repeatable)");
  cmd->add_option("--label-names,--label_names", o.labelNames,
                  "Colour table for every case without its own (manifest column)");
  cmd->add_flag("--force", o.force, "Mesh every case again, even those up to date");
  cmd->add_flag("-q,--quiet", o.quiet, "Only the final line and errors");
  cmd->add_option("--summarise-only,--summarize-only", o.summariseOnly,
                  "Only write the summary of this output folder's cases (e.g. after a Snakemake "
                  "run); no meshing");
  cmd->add_flag("--list", o.list, "Print the cases the inputs name (JSON: case, label_map, "
                                  "parameters, label_names) and exit");
  return cmd;
}

int runBatch(const BatchOptions& o) {
  if (!o.summariseOnly.empty()) {
    if (!fs::is_directory(o.summariseOnly))
      return fail({ErrorCode::FileNotFound, "'" + o.summariseOnly + "' is not a folder."});
    const auto cases = scanCaseFolders(o.summariseOnly);
    if (Status s = writeCohortSummary(o.summariseOnly, cases); !s) return fail(s);
    int failed = 0;
    for (const auto& c : cases) failed += c.status != "ok";
    std::fprintf(stderr, "batch: summary of %zu case(s), %d failed: %s\n", cases.size(), failed,
                 (fs::path(o.summariseOnly) / "summary.html").c_str());
    return failed ? kBatchCasesFailedExit : 0;
  }
  if (o.inputs.empty()) return fail({ErrorCode::InvalidArgument, "No input: give label maps, "
                                     "folders, glob patterns or a CSV manifest."});
  if (o.list) {
    std::vector<Case> cases;
    if (Status s = collectCases(o.inputs, cases); !s) return fail(s);
    json list = json::array();
    for (const auto& c : cases)
      list.push_back({{"case", c.id}, {"label_map", c.input},
                      {"parameters", c.parameterFile.empty() ? o.parameterFile : c.parameterFile},
                      {"label_names", c.labelNames.empty() ? o.labelNames : c.labelNames}});
    std::printf("%s\n", list.dump(1).c_str());
    return 0;
  }
  if (o.outDir.empty())
    return fail({ErrorCode::InvalidArgument, "No output folder: give -o OUTDIR."});
  std::vector<std::string> formats = o.formats.empty() ? std::vector<std::string>{"vtu"} : o.formats;
  static const std::set<std::string> known = {"vtu", "vtk", "inp", "msh", "mesh", "feb", "stl"};
  for (auto& f : formats) {
    if (!f.empty() && f[0] == '.') f.erase(0, 1);
    if (!known.count(f))
      return fail({ErrorCode::InvalidArgument,
                   "--format '" + f + "' is not a mesh format: vtu vtk inp msh mesh feb stl."});
  }
  if (o.jobs < 0 || o.threads < 0)
    return fail({ErrorCode::InvalidArgument, "--jobs and --threads must be positive."});
  std::vector<Case> cases;
  if (Status s = collectCases(o.inputs, cases); !s) return fail(s);
  std::error_code ec;
  fs::create_directories(o.outDir, ec);
  if (ec || !fs::is_directory(o.outDir))
    return fail({ErrorCode::WriteFailed, "Cannot create the output folder '" + o.outDir + "'."});

  // Arguments of every case's `femesher mesh`, its fingerprint, and what is up to date.
  std::vector<size_t> todo;
  int upToDateCount = 0;
  for (size_t i = 0; i < cases.size(); ++i) {
    Case& c = cases[i];
    c.dir = (fs::path(o.outDir) / c.id).string();
    if (c.parameterFile.empty()) c.parameterFile = o.parameterFile;
    if (c.labelNames.empty()) c.labelNames = o.labelNames;
    c.args = {"mesh", c.input};
    for (const auto& out : caseOutputs(c, formats)) {
      const std::string name = fs::path(out).filename().string();
      const char* flag = name == kCaseReport ? "--report"
                         : name == "parameters.json" ? "--save-parameters" : "-o";
      c.args.insert(c.args.end(), {flag, out});
    }
    if (!o.preset.empty()) c.args.insert(c.args.end(), {"--preset", o.preset});
    if (!c.parameterFile.empty()) c.args.insert(c.args.end(), {"--parameters", c.parameterFile});
    if (!c.labelNames.empty()) c.args.insert(c.args.end(), {"--label-names", c.labelNames});
    for (const auto& s : o.sets) c.args.insert(c.args.end(), {"--set", s});
    c.settings = {"--format"};
    c.settings.insert(c.settings.end(), formats.begin(), formats.end());
    c.settings.insert(c.settings.end(), {"--preset", o.preset});
    for (const auto& s : o.sets) c.settings.insert(c.settings.end(), {"--set", s});
    c.fingerprint = caseFingerprint(c);
    c.record.id = c.id;
    c.record.dir = c.dir;
    c.record.input = c.input;
    if (!o.force && upToDate(c, formats)) {
      std::ifstream in(fs::path(c.dir) / kCaseRecord);
      c.record.status = "ok";
      c.record.run = "up_to_date";
      c.record.exitCode = 0;
      c.record.wallSeconds = json::parse(in).value("wall_seconds", -1.0);
      ++upToDateCount;
      continue;
    }
    fs::create_directories(c.dir, ec);
    // A fresh log per run of the case; its record goes (a failure is recorded again).
    std::ofstream(fs::path(c.dir) / kCaseLog, std::ios::trunc);
    fs::remove(fs::path(c.dir) / kCaseRecord, ec);
    c.record.status = "not_run";
    c.record.run = "not_run";
    todo.push_back(i);
  }

  struct sigaction sa {};
  sa.sa_handler = onBatchSignal;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = 0;  // no SA_RESTART: a signal cuts the wait short
  struct sigaction oldInt {}, oldTerm {};
  ::sigaction(SIGINT, &sa, &oldInt);
  ::sigaction(SIGTERM, &sa, &oldTerm);

  // The rule (README *Cohorts*): jobs = --jobs or min(cores, cases to mesh); threads per case =
  // --threads or max(1, cores / jobs); a case starts only while the memory estimates of the
  // running cases and its own (at its thread count) fit in the memory available at the start
  // (MemoryEstimate.h), except when nothing else runs; the largest estimates start first.
  const int cores = usableCores();
  const int jobs = o.jobs > 0 ? o.jobs : std::max(1, std::min<int>(cores, int(todo.size())));
  const int threads = o.threads > 0 ? o.threads : std::max(1, cores / jobs);
  std::string source;
  const uintmax_t available = memoryAvailableForRun(&source);
  if (!o.quiet)
    std::fprintf(stderr, "batch: %zu case(s), %d up to date, %zu to mesh; %d at a time, %d "
                 "thread(s) each (%d cores, %.1f GB available from %s)\n", cases.size(),
                 upToDateCount, todo.size(), jobs, threads, cores, double(available) / 1e9,
                 source.c_str());
  const auto batchStart = std::chrono::steady_clock::now();
  estimateCases(cases, todo, std::max(jobs, cores), threads);
  std::vector<size_t> queue;
  for (size_t i : todo)
    if (cases[i].perProcessBytes > 0) queue.push_back(i);
  std::stable_sort(queue.begin(), queue.end(), [&](size_t a, size_t b) {
    return peakFor(cases[a], threads) > peakFor(cases[b], threads);
  });

  std::map<pid_t, Running> running;
  uintmax_t booked = 0;
  size_t done = todo.size() - queue.size();  // estimates that failed count as done
  bool forwarded = false;
  std::vector<size_t>::iterator next = queue.begin();
  for (size_t i : todo)
    if (cases[i].record.status == "failed" && !o.quiet)
      std::fprintf(stderr, "batch: %s failed (exit %d) before meshing: %s\n", cases[i].id.c_str(),
                   cases[i].record.exitCode, cases[i].record.error.c_str());
  while (!gBatchSignal ? (next != queue.end() || !running.empty()) : !running.empty()) {
    forwardSignal(running, forwarded);
    while (!gBatchSignal && next != queue.end() && int(running.size()) < jobs) {
      Case& c = cases[*next];
      const uintmax_t need = peakFor(c, threads);
      if (!running.empty() && available > 0 && booked + need > available) break;
      std::vector<std::string> args = c.args;
      args.insert(args.end(), {"--threads", std::to_string(threads)});
      const pid_t pid = spawn(args, (fs::path(c.dir) / kCaseLog).string(), -1);
      running[pid] = {*next, std::chrono::steady_clock::now(), -1, need};
      c.startedUnix = unixNow();
      booked += need;
      ++next;
    }
    int status = 0;
    const pid_t pid = reap(status);
    if (pid <= 0 || !running.count(pid)) continue;
    const Running r = running[pid];
    running.erase(pid);
    booked -= r.bytes;
    Case& c = cases[r.index];
    c.record.exitCode = exitCodeOf(status);
    c.record.wallSeconds = secondsSince(r.start);
    c.record.run = "meshed";
    const std::string log = (fs::path(c.dir) / kCaseLog).string();
    if (c.record.exitCode == 0) {
      c.record.status = "ok";
    } else {
      c.record.status = c.record.exitCode == exitCodeFor(ErrorCode::Canceled) && gBatchSignal
                            ? "canceled"
                            : "failed";
      c.record.error = errorOf(log);
      if (WIFSIGNALED(status))  // a crash or a kill: say so, the log may be empty
        c.record.error = "killed by signal " + std::to_string(WTERMSIG(status)) + " (" +
                         strsignal(WTERMSIG(status)) + ")" +
                         (c.record.error.empty() ? "" : "; " + c.record.error);
    }
    if (c.record.status != "canceled") {
      if (Status s = writeRecord(c); !s) std::fprintf(stderr, "warning: %s\n", s.message().c_str());
    }
    ++done;
    if (!o.quiet)
      std::fprintf(stderr, "batch: [%zu/%zu] %s %s (exit %d) %.1f s%s%s\n", done, todo.size(),
                   c.id.c_str(), c.record.status.c_str(), c.record.exitCode,
                   c.record.wallSeconds, c.record.error.empty() ? "" : ": ",
                   c.record.error.empty() ? "" : lastLines(log, 1).c_str());
  }
  // Failed estimates were recorded in phase 1; record them (not canceled ones) for the summary.
  for (size_t i : todo)
    if (cases[i].record.status == "failed" && cases[i].perProcessBytes == 0) writeRecord(cases[i]);

  std::vector<CaseRecord> records;
  int failed = 0, canceled = 0, notRun = 0;
  for (const auto& c : cases) {
    records.push_back(c.record);
    failed += c.record.status == "failed";
    canceled += c.record.status == "canceled";
    notRun += c.record.status == "not_run";
  }
  const Status written = writeCohortSummary(o.outDir, records);
  ::sigaction(SIGINT, &oldInt, nullptr);
  ::sigaction(SIGTERM, &oldTerm, nullptr);
  std::fprintf(stderr, "batch: %zu case(s): %zu ok (%d up to date), %d failed, %d canceled, %d "
               "not run; %.1f s; summary: %s\n", cases.size(),
               cases.size() - size_t(failed + canceled + notRun), upToDateCount, failed, canceled,
               notRun, secondsSince(batchStart),
               (fs::path(o.outDir) / "summary.html").c_str());
  if (!written) return fail(written);
  if (gBatchSignal) {
    std::fprintf(stderr, "error [%s]: The batch was canceled.\n",
                 errorCodeName(ErrorCode::Canceled));
    return exitCodeFor(ErrorCode::Canceled);
  }
  return failed ? kBatchCasesFailedExit : 0;
}

}  // namespace femesher::cli
