// SPDX-License-Identifier: GPL-3.0-or-later
// TetGen jobs of the VolumeMesh stage (see internal/TetgenJobs.h).
#include <femesher/MemoryEstimate.h>
#include <femesher/Status.h>
#include <femesher/stages/internal/TetgenJobs.h>

#include <dlfcn.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/mman.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstdio>
#include <cstring>
#include <string>

extern char** environ;

namespace femesher {
namespace volume_detail {

namespace {

/// Child side (fork): mesh, stream the result through `fd`, leave without running any exit
/// handler.
[[noreturn]] void runChild(const TetgenInput& input, const std::string& switches, int fd) {
  TetgenOutput r;
  std::string err;
  const bool ok = runTetgen(input, switches, r, err);
  const bool w = writeResult(fd, ok, r, err);
  ::close(fd);
  ::_exit(w ? 0 : 3);
}

/// Starts the worker on one problem: the problem in an anonymous memory file as its standard
/// input, a pipe as its standard output (`readFd`, the parent's end). Returns its pid, or -1 when
/// it could not start (the caller forks instead).
pid_t spawnWorker(const std::string& worker, const TetgenInput& in, const std::string& switches,
                  int& readFd) {
  readFd = -1;
  const int mem = ::memfd_create("femesher-tetgen-input", MFD_CLOEXEC);
  if (mem < 0) return -1;
  int fds[2] = {-1, -1};
  // A descriptor numbered 0 or 1 (this process runs without standard input or output) would be
  // its own dup2 target, which keeps its close-on-exec flag: fork instead.
  if (mem < 3 || !writeInput(mem, in) || ::lseek(mem, 0, SEEK_SET) != 0 ||
      ::pipe2(fds, O_CLOEXEC) != 0 || fds[1] < 3) {
    ::close(mem);
    if (fds[0] >= 0) ::close(fds[0]);
    if (fds[1] >= 0) ::close(fds[1]);
    return -1;
  }
  posix_spawn_file_actions_t actions;
  ::posix_spawn_file_actions_init(&actions);
  ::posix_spawn_file_actions_adddup2(&actions, mem, 0);
  ::posix_spawn_file_actions_adddup2(&actions, fds[1], 1);
  const std::string parent = std::to_string(::getpid());
  std::string sw = switches;
  std::string path = worker;
  char* argv[] = {path.data(), sw.data(), const_cast<char*>(parent.c_str()), nullptr};
  pid_t pid = -1;
  const int rc = ::posix_spawn(&pid, worker.c_str(), &actions, nullptr, argv, environ);
  ::posix_spawn_file_actions_destroy(&actions);
  ::close(mem);
  ::close(fds[1]);
  if (rc != 0) {
    ::close(fds[0]);
    return -1;
  }
  readFd = fds[0];
  return pid;
}

/// Parent side: decodes what a child streamed.
JobResult decodeChild(const std::vector<char>& buffer, int wstatus) {
  JobResult res;
  size_t pos = 0;
  auto take = [&](void* dst, size_t n) {
    if (pos + n > buffer.size()) return false;
    std::memcpy(dst, buffer.data() + pos, n);
    pos += n;
    return true;
  };
  int32_t status = -1;
  if (!take(&status, sizeof status)) {
    res.error = WIFSIGNALED(wstatus)
                    ? "TetGen crashed (signal " + std::to_string(WTERMSIG(wstatus)) + ")"
                    : "TetGen ended without a result (its process exited with code " +
                          std::to_string(WIFEXITED(wstatus) ? WEXITSTATUS(wstatus) : -1) + ")";
    return res;
  }
  if (status != 0) {
    uint64_t len = 0;
    if (take(&len, sizeof len) && pos + len <= buffer.size())
      res.error.assign(buffer.data() + pos, size_t(len));
    else
      res.error = "TetGen failed";
    return res;
  }
  uint64_t n[3];
  if (!take(n, sizeof n)) {
    res.error = "TetGen result was cut short";
    return res;
  }
  TetgenOutput& r = res.out;
  r.points.resize(n[0]);
  r.tets.resize(n[1]);
  r.regions.resize(n[2]);
  if (!take(r.points.data(), n[0] * sizeof(double)) ||
      !take(r.tets.data(), n[1] * sizeof(int32_t)) ||
      !take(r.regions.data(), n[2] * sizeof(double))) {
    res.error = "TetGen result was cut short";
    return res;
  }
  res.ok = true;
  return res;
}

}  // namespace

std::string tetgenWorkerPath() {
  if (const char* e = std::getenv("FEMESHER_TETGEN_WORKER"))
    return *e && ::access(e, X_OK) == 0 ? std::string(e) : std::string();
  Dl_info info{};
  if (::dladdr(reinterpret_cast<void*>(&tetgenWorkerPath), &info) == 0 || !info.dli_fname)
    return {};
  const std::string lib = info.dli_fname;
  const size_t slash = lib.rfind('/');
  const std::string dir = slash == std::string::npos ? "." : lib.substr(0, slash);
  for (const std::string& c : {dir + "/../bin/femesher-tetgen-worker", dir + "/femesher-tetgen-worker"})
    if (::access(c.c_str(), X_OK) == 0) return c;
  return {};
}

std::vector<JobResult> runTetgenJobs(const std::vector<TetgenInput>& inputs,
                                     const std::string& switches, int parallel, RunContext& ctx,
                                     double p0, double p1) {
  struct Running {
    size_t job;
    pid_t pid;
    int fd;
    std::vector<char> buffer;
  };
  std::vector<JobResult> results(inputs.size());
  std::vector<Running> running;
  size_t next = 0, doneTriangles = 0, allTriangles = 0;
  for (const auto& in : inputs) allTriangles += in.triangles.size();
  auto killAll = [&] {
    for (auto& r : running) {
      ::kill(r.pid, SIGKILL);
      ::close(r.fd);
      int ws = 0;
      while (::waitpid(r.pid, &ws, 0) < 0 && errno == EINTR) {
      }
    }
    running.clear();
  };
  const std::string worker = tetgenWorkerPath();
  // The helpers side by side must fit in the memory the machine offers as they start (0:
  // unknown, no bound); one runs alone whatever it needs.
  const uintmax_t budget = memoryAvailableForRun();
  uintmax_t runningBytes = 0;
  bool heldBack = false;
  auto fits = [&](size_t j) {
    return running.empty() || budget == 0 || runningBytes + tetgenHelperBytes(inputs[j]) <= budget;
  };
  while (next < inputs.size() || !running.empty()) {
    if (ctx.isCanceled()) {
      killAll();
      ctx.checkCancel();
    }
    while (next < inputs.size() && int(running.size()) < std::max(1, parallel)) {
      if (!fits(next)) {
        heldBack = true;
        break;
      }
      const size_t j = next++;
      int fds[2];
      pid_t pid = worker.empty() ? -1 : spawnWorker(worker, inputs[j], switches, fds[0]);
      if (pid < 0 && ::pipe(fds) == 0) {
        const pid_t parent = ::getpid();
        pid = ::fork();
        if (pid == 0) {
          dieWithParent(parent);
          ::close(fds[0]);
          runChild(inputs[j], switches, fds[1]);
        }
        ::close(fds[1]);
        if (pid < 0) ::close(fds[0]);
      }
      if (pid < 0) {  // no child: mesh here (cannot be canceled midway)
        results[j].ok = runTetgen(inputs[j], switches, results[j].out, results[j].error);
        doneTriangles += inputs[j].triangles.size();
        continue;
      }
      running.push_back({j, pid, fds[0], {}});
      runningBytes += tetgenHelperBytes(inputs[j]);
    }
    if (running.empty()) continue;
    std::vector<pollfd> pfds;
    for (const auto& r : running) pfds.push_back({r.fd, POLLIN, 0});
    const int pr = ::poll(pfds.data(), nfds_t(pfds.size()), 100);
    if (pr < 0 && errno != EINTR) {
      killAll();
      throw Error(ErrorCode::MeshingFailed, "Volume meshing failed: poll() on TetGen's pipes failed.");
    }
    if (pr <= 0) continue;
    char chunk[1 << 16];
    for (size_t q = pfds.size(); q-- > 0;) {
      if (!(pfds[q].revents & (POLLIN | POLLHUP | POLLERR))) continue;
      Running& r = running[q];
      const ssize_t n = ::read(r.fd, chunk, sizeof chunk);
      if (n < 0 && errno == EINTR) continue;
      if (n > 0) {
        r.buffer.insert(r.buffer.end(), chunk, chunk + n);
        continue;
      }
      ::close(r.fd);
      int wstatus = 0;
      while (::waitpid(r.pid, &wstatus, 0) < 0 && errno == EINTR) {
      }
      results[r.job] = decodeChild(r.buffer, wstatus);
      doneTriangles += inputs[r.job].triangles.size();
      runningBytes -= tetgenHelperBytes(inputs[r.job]);
      running.erase(running.begin() + std::ptrdiff_t(q));
      ctx.progress(p0 + (p1 - p0) * double(doneTriangles) / double(std::max<size_t>(1, allTriangles)));
    }
  }
  if (heldBack) {
    uintmax_t largest = 0;
    for (const auto& in : inputs) largest = std::max(largest, tetgenHelperBytes(in));
    auto size = [](uintmax_t bytes) {
      char t[32];
      if (bytes >= 1000000000u) std::snprintf(t, sizeof t, "%.1f GB", double(bytes) / 1e9);
      else std::snprintf(t, sizeof t, "%.0f MB", double(bytes) / 1e6);
      return std::string(t);
    };
    ctx.warn("Volume meshing ran fewer TetGen helpers side by side than threads: the largest "
             "needs about " + size(largest) + " and " + size(budget) + " were available; the mesh "
             "is the same, the stage took longer.");
  }
  return results;
}

uintmax_t tetgenHelperBytes(const TetgenInput& input) {
  return uintmax_t(kTetgenHelperBytesPerTriangle * double(input.triangles.size())) + (8u << 20);
}
}  // namespace volume_detail
}  // namespace femesher
