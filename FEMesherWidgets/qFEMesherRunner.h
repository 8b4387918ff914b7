// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file qFEMesherRunner.h
/// Runs `femesher::runPipeline` in a worker QThread so the GUI never blocks.
///
/// The worker never touches widgets. It writes the latest progress, log lines and the latest
/// preview snapshot into a mutex-protected mailbox; a GUI-thread timer (every `pollInterval`
/// ms) empties it and emits the signals below. So a flood of progress callbacks or previews
/// costs the GUI at most one update per tick (natural throttling), and every signal is emitted
/// on the GUI thread. Only progress within a stage is coalesced: every stage the run enters is
/// forwarded (its first report, then the latest), however short the stage or late the tick. `cancel()` calls `RunContext::cancel()`; the pipeline checks the token in
/// its loops and ends with a Canceled status.

#include <femesher/Parameters.h>
#include <femesher/Pipeline.h>
#include <femesher/RunContext.h>
#include <femesher/Types.h>

#include <QObject>
#include <QString>
#include <QStringList>

#include <chrono>
#include <memory>
#include <mutex>
#include <vector>

class QThread;
class QTimer;

Q_DECLARE_METATYPE(std::shared_ptr<const femesher::PreviewSnapshot>)
Q_DECLARE_METATYPE(std::shared_ptr<const femesher::PipelineResult>)

class qFEMesherRunner : public QObject {
  Q_OBJECT
 public:
  explicit qFEMesherRunner(QObject* parent = nullptr);
  ~qFEMesherRunner() override;  ///< cancels and joins a running worker

  /// Start a run on a copy-free shared volume. Returns false if a run is already going.
  bool start(std::shared_ptr<const femesher::LabelVolume> volume,
             const femesher::MeshingParameters& params);
  bool isRunning() const { return running_; }
  /// Request cancellation (returns immediately; `canceled()` follows when the worker stopped).
  void cancel();
  /// Block (processing no events) until the worker has ended; true if it ended in time.
  bool wait(int msecs);

  /// GUI refresh period for progress/preview/log forwarding (default 100 ms).
  void setPollInterval(int msecs);
  /// Seconds between the last cancel() and the worker's end (negative when not canceled).
  double lastCancelLatency() const { return cancelLatency_; }

  std::shared_ptr<const femesher::PipelineResult> lastResult() const { return result_; }

 signals:
  void started();
  /// stage name, fraction of the stage, fraction of the whole run (0..1)
  void progressChanged(const QString& stage, double stageFraction, double totalFraction);
  void logMessage(int level, const QString& message);  ///< level: femesher::LogLevel
  void previewAvailable(std::shared_ptr<const femesher::PreviewSnapshot> snapshot);
  void succeeded(std::shared_ptr<const femesher::PipelineResult> result);
  void failed(int errorCode, const QString& message);
  void canceled();
  /// Always emitted last, after succeeded/failed/canceled.
  void finished();

 private slots:
  void poll();
  void onThreadFinished();

 private:
  struct Mailbox {
    std::mutex mutex;
    QString stage;
    double stageFraction = 0, total = 0;
    bool progressDirty = false;
    struct Progress {
      QString stage;
      double stageFraction, total;
    };
    std::vector<Progress> entered;  ///< first report of each stage begun since the last tick
    std::vector<std::pair<int, QString>> logs;
    std::shared_ptr<const femesher::PreviewSnapshot> preview;
    // outcome
    bool done = false;
    std::shared_ptr<const femesher::PipelineResult> result;
    int errorCode = 0;
    QString errorMessage;
  };

  std::shared_ptr<Mailbox> box_;
  std::shared_ptr<femesher::RunContext> ctx_;
  QThread* thread_ = nullptr;
  QTimer* timer_ = nullptr;
  bool running_ = false;
  std::shared_ptr<const femesher::PipelineResult> result_;
  std::chrono::steady_clock::time_point cancelTime_{};
  bool cancelRequested_ = false;
  double cancelLatency_ = -1;
};
