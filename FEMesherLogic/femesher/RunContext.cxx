// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/RunContext.h>
#include <femesher/Status.h>

#include <algorithm>

namespace femesher {

void RunContext::setStagePlan(std::vector<std::pair<std::string, double>> plan) {
  plan_ = std::move(plan);
  totalWeight_ = 0;
  for (const auto& p : plan_) totalWeight_ += p.second;
  if (totalWeight_ <= 0) totalWeight_ = 1;
  doneWeight_ = 0;
  stageWeight_ = 0;
  lastReported_ = -1;
}

void RunContext::beginStage(const std::string& name) {
  checkCancel();
  // Weight of stages before this one in the plan counts as done (stages may be skipped).
  doneWeight_ = 0;
  stageWeight_ = 0;
  for (const auto& p : plan_) {
    if (p.first == name) {
      stageWeight_ = p.second;
      break;
    }
    doneWeight_ += p.second;
  }
  if (std::none_of(plan_.begin(), plan_.end(), [&](const auto& p) { return p.first == name; }))
    doneWeight_ = std::max(0.0, lastReported_) * totalWeight_;
  stage_ = name;
  lastProgressTime_ = {};
  progress(0.0);
}

void RunContext::progress(double fraction) {
  checkCancel();
  if (!progressCb_) return;
  fraction = std::clamp(fraction, 0.0, 1.0);
  const double total = std::clamp((doneWeight_ + fraction * stageWeight_) / totalWeight_, 0.0, 1.0);
  const auto now = std::chrono::steady_clock::now();
  // Throttle: report at most every 50 ms unless a stage starts or ends.
  if (fraction > 0.0 && fraction < 1.0 && now - lastProgressTime_ < std::chrono::milliseconds(50))
    return;
  lastProgressTime_ = now;
  lastReported_ = std::max(lastReported_, total);
  progressCb_(stage_, fraction, lastReported_);
}

void RunContext::endStage() {
  progress(1.0);
  doneWeight_ += stageWeight_;
  stageWeight_ = 0;
}

void RunContext::checkCancel() const {
  if (cancel_.isCanceled()) throw Error(ErrorCode::Canceled, "The run was canceled.");
}

void RunContext::log(LogLevel level, const std::string& message) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (level == LogLevel::Warning) warnings_.push_back(message);
  }
  if (logCb_) logCb_(level, message);
}

std::vector<std::string> RunContext::warnings() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return warnings_;
}

void RunContext::preview(std::shared_ptr<const PreviewSnapshot> snapshot, bool force) {
  if (!previewCb_ || !snapshot) return;
  const auto now = std::chrono::steady_clock::now();
  if (!force && now - lastPreview_ < previewInterval_) return;
  lastPreview_ = now;
  previewCb_(std::move(snapshot));
}

}  // namespace femesher
