// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file RunContext.h
/// What every stage receives besides its input and parameters: weighted progress, a cooperative
/// cancel token, a throttled preview sink and a logger. No globals: two runs can coexist.
///
/// Progress: the pipeline declares its stages with weights (`setStagePlan`); a stage calls
/// `beginStage(name)` then `progress(fraction in [0,1])`. The total fraction is the weighted sum.
/// Cancel: any thread may call `cancel()`. Stages call `checkCancel()` (also done by `progress`)
/// inside long loops; it throws `Error(ErrorCode::Canceled)` which the pipeline turns into a
/// Canceled status. Callbacks are invoked on the thread that runs the pipeline.

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

namespace femesher {

enum class LogLevel { Debug, Info, Warning };

/// An immutable snapshot for live display (GUI). Points are in physical LPS mm.
struct PreviewSnapshot {
  std::string stage;   ///< stage that produced it, e.g. "SurfaceSampling"
  std::string kind;    ///< "points" (particles) or "surface" (triangles)
  std::vector<std::array<float, 3>> points;
  std::vector<int32_t> pointGroup;              ///< per point: index into `groups`
  std::vector<std::pair<int32_t, int32_t>> groups;  ///< material (user id) pairs, b may be -1
  std::vector<std::array<int32_t, 3>> triangles;    ///< for kind == "surface"
  int iteration = 0;
};

class CancelToken {
 public:
  void cancel() { flag_.store(true); }
  bool isCanceled() const { return flag_.load(std::memory_order_relaxed); }
  void reset() { flag_.store(false); }
  std::atomic<bool>* flag() { return &flag_; }

 private:
  std::atomic<bool> flag_{false};
};

class RunContext {
 public:
  /// (stage name, fraction of the stage, fraction of the whole run)
  using ProgressCallback = std::function<void(const std::string&, double, double)>;
  using LogCallback = std::function<void(LogLevel, const std::string&)>;
  using PreviewCallback = std::function<void(std::shared_ptr<const PreviewSnapshot>)>;

  RunContext() = default;
  RunContext(const RunContext&) = delete;
  RunContext& operator=(const RunContext&) = delete;

  void setProgressCallback(ProgressCallback cb) { progressCb_ = std::move(cb); }
  void setLogCallback(LogCallback cb) { logCb_ = std::move(cb); }
  void setPreviewCallback(PreviewCallback cb) { previewCb_ = std::move(cb); }
  /// Minimum interval between two previews (default 150 ms).
  void setPreviewInterval(std::chrono::milliseconds ms) { previewInterval_ = ms; }
  bool wantsPreview() const { return static_cast<bool>(previewCb_); }

  /// Declare the stages of the run and their relative weights.
  void setStagePlan(std::vector<std::pair<std::string, double>> plan);
  /// Start a stage (must be in the plan; unknown stages get weight 0).
  void beginStage(const std::string& name);
  /// Progress within the current stage, fraction in [0,1]. Also checks cancel.
  void progress(double fraction);
  /// Finish the current stage (reports fraction 1).
  void endStage();
  const std::string& currentStage() const { return stage_; }

  CancelToken& cancelToken() { return cancel_; }
  void cancel() { cancel_.cancel(); }
  bool isCanceled() const { return cancel_.isCanceled(); }
  /// Throws Error(Canceled) when cancel was requested.
  void checkCancel() const;

  void log(LogLevel level, const std::string& message);
  void info(const std::string& message) { log(LogLevel::Info, message); }
  void debug(const std::string& message) { log(LogLevel::Debug, message); }
  /// Warnings are also collected for the run report.
  void warn(const std::string& message) { log(LogLevel::Warning, message); }
  std::vector<std::string> warnings() const;

  /// Send a preview snapshot (dropped if one was sent less than the interval ago, unless force).
  void preview(std::shared_ptr<const PreviewSnapshot> snapshot, bool force = false);

  /// Threads to use (0 = all hardware threads). Stages read this.
  int threads() const { return threads_; }
  void setThreads(int n) { threads_ = n; }

 private:
  ProgressCallback progressCb_;
  LogCallback logCb_;
  PreviewCallback previewCb_;
  CancelToken cancel_;
  std::vector<std::pair<std::string, double>> plan_;
  std::string stage_;
  double doneWeight_ = 0, stageWeight_ = 0, totalWeight_ = 1;
  double lastReported_ = -1;
  std::chrono::steady_clock::time_point lastProgressTime_{};
  std::chrono::milliseconds previewInterval_{150};
  std::chrono::steady_clock::time_point lastPreview_{};
  mutable std::mutex mutex_;
  std::vector<std::string> warnings_;
  int threads_ = 0;
};

}  // namespace femesher
