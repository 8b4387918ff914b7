// SPDX-License-Identifier: GPL-3.0-or-later
#include "qFEMesherRunner.h"

#include <femesher/Status.h>

#include <QThread>
#include <QTimer>

namespace {
struct MetaTypeRegistration {
  MetaTypeRegistration() {
    qRegisterMetaType<std::shared_ptr<const femesher::PreviewSnapshot>>();
    qRegisterMetaType<std::shared_ptr<const femesher::PipelineResult>>();
  }
} metaTypeRegistration;
}  // namespace

qFEMesherRunner::qFEMesherRunner(QObject* parent) : QObject(parent) {
  timer_ = new QTimer(this);
  timer_->setInterval(100);
  connect(timer_, &QTimer::timeout, this, &qFEMesherRunner::poll);
}

qFEMesherRunner::~qFEMesherRunner() {
  if (thread_) {
    if (ctx_) ctx_->cancel();
    thread_->wait();
    delete thread_;
    thread_ = nullptr;
  }
}

void qFEMesherRunner::setPollInterval(int msecs) { timer_->setInterval(std::max(10, msecs)); }

bool qFEMesherRunner::start(std::shared_ptr<const femesher::LabelVolume> volume,
                            const femesher::MeshingParameters& params) {
  if (running_ || !volume) return false;
  if (thread_) {  // a finished thread whose finished() has not been processed yet
    thread_->wait();
    delete thread_;
    thread_ = nullptr;
  }
  box_ = std::make_shared<Mailbox>();
  ctx_ = std::make_shared<femesher::RunContext>();
  result_.reset();
  cancelRequested_ = false;
  cancelLatency_ = -1;

  std::weak_ptr<Mailbox> weakBox = box_;
  auto box = box_;
  ctx_->setProgressCallback([box](const std::string& stage, double f, double total) {
    std::lock_guard<std::mutex> lock(box->mutex);
    QString name = QString::fromStdString(stage);
    if (name != box->stage) box->entered.push_back({name, f, total});
    box->stage = std::move(name);
    box->stageFraction = f;
    box->total = total;
    box->progressDirty = true;
  });
  ctx_->setLogCallback([box](femesher::LogLevel level, const std::string& msg) {
    std::lock_guard<std::mutex> lock(box->mutex);
    if (box->logs.size() < 10000) box->logs.emplace_back(int(level), QString::fromStdString(msg));
  });
  ctx_->setPreviewCallback([box](std::shared_ptr<const femesher::PreviewSnapshot> s) {
    std::lock_guard<std::mutex> lock(box->mutex);
    box->preview = std::move(s);  // only the newest one matters
  });

  auto ctx = ctx_;
  const femesher::MeshingParameters p = params;
  thread_ = QThread::create([box, ctx, volume, p]() {
    std::shared_ptr<femesher::PipelineResult> out;
    int code = 0;
    QString message;
    try {
      // The panel can switch the element order to 2 after a run: keep what curving needs.
      femesher::PipelineOptions options;
      options.keepCurvingData = true;
      auto r = femesher::runPipeline(*volume, p, *ctx, options);
      if (r) out = std::make_shared<femesher::PipelineResult>(std::move(r).value());
      else {
        code = int(r.status().code());
        message = QString::fromStdString(r.status().message());
      }
    } catch (const femesher::Error& e) {
      code = int(e.code());
      message = QString::fromUtf8(e.what());
    } catch (const std::exception& e) {
      code = int(femesher::ErrorCode::Internal);
      message = QString::fromUtf8(e.what());
    }
    std::lock_guard<std::mutex> lock(box->mutex);
    box->done = true;
    box->result = std::move(out);
    box->errorCode = code;
    box->errorMessage = message;
  });
  connect(thread_, &QThread::finished, this, &qFEMesherRunner::onThreadFinished);
  running_ = true;
  emit started();
  thread_->start();
  timer_->start();
  return true;
}

void qFEMesherRunner::cancel() {
  if (!running_ || !ctx_) return;
  if (!cancelRequested_) {
    cancelRequested_ = true;
    cancelTime_ = std::chrono::steady_clock::now();
  }
  ctx_->cancel();
}

bool qFEMesherRunner::wait(int msecs) {
  if (!thread_) return true;
  return thread_->wait(msecs < 0 ? ULONG_MAX : static_cast<unsigned long>(msecs));
}

void qFEMesherRunner::poll() {
  if (!box_) return;
  QString stage;
  double f = 0, total = 0;
  bool dirty = false;
  std::vector<std::pair<int, QString>> logs;
  std::vector<Mailbox::Progress> entered;
  std::shared_ptr<const femesher::PreviewSnapshot> preview;
  {
    std::lock_guard<std::mutex> lock(box_->mutex);
    entered.swap(box_->entered);
    dirty = box_->progressDirty;
    box_->progressDirty = false;
    stage = box_->stage;
    f = box_->stageFraction;
    total = box_->total;
    logs.swap(box_->logs);
    preview.swap(box_->preview);
  }
  for (const auto& [level, msg] : logs) emit logMessage(level, msg);
  // Stages begun and left since the last tick, then where the run is now.
  for (const auto& e : entered)
    if (e.stage != stage) emit progressChanged(e.stage, e.stageFraction, e.total);
  if (dirty) emit progressChanged(stage, f, total);
  if (preview) emit previewAvailable(preview);
}

void qFEMesherRunner::onThreadFinished() {
  if (!running_) return;
  timer_->stop();
  poll();  // flush the last progress, logs and preview
  if (cancelRequested_)
    cancelLatency_ =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - cancelTime_).count();
  std::shared_ptr<const femesher::PipelineResult> result;
  int code = 0;
  QString message;
  {
    std::lock_guard<std::mutex> lock(box_->mutex);
    result = box_->result;
    code = box_->errorCode;
    message = box_->errorMessage;
  }
  thread_->deleteLater();
  thread_ = nullptr;
  running_ = false;
  if (result) {
    result_ = result;
    emit succeeded(result);
  } else if (code == int(femesher::ErrorCode::Canceled)) {
    emit canceled();
  } else {
    emit failed(code, message);
  }
  emit finished();
}
