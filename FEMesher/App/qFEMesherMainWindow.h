// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file qFEMesherMainWindow.h
/// FEMesherApp's window: the panel on the left, the 3-D view and the quality histograms on the
/// right; File > Open / Open sample / recent files, drag-and-drop of label maps, About.
/// `startScript` drives it from the command line (open, run, screenshots, export, exit).

#include <femesher/Pipeline.h>

#include <QMainWindow>
#include <QStringList>

#include <memory>

class QMenu;
class qFEMesherPanelWidget;
class qFEMesherPreviewView;
class qFEMesherQualityHistogramWidget;

class qFEMesherMainWindow : public QMainWindow {
  Q_OBJECT
 public:
  struct Script {
    QString open;
    bool sample = false;
    QString preset;
    QString parameters;
    bool run = false;
    QString screenshot;
    QString screenshotDir;
    QStringList exports;
    bool exit = false;
  };

  explicit qFEMesherMainWindow(QWidget* parent = nullptr);
  ~qFEMesherMainWindow() override;

  bool openFile(const QString& path);
  /// Writes the built-in phantom to a temporary .nrrd and opens it.
  bool openSample();
  /// The window as shown, with the VTK render window composited in (works under xvfb).
  /// `settle` first processes pending events (layout, queued results); off for mid-run pictures.
  QImage grabWindowImage(bool settle = true);
  bool saveScreenshot(const QString& path, bool settle = true);
  void startScript(const Script& script);

  qFEMesherPanelWidget* panel() const { return panel_; }
  qFEMesherPreviewView* view() const { return view_; }
  qFEMesherQualityHistogramWidget* histograms() const { return histograms_; }

  static bool isLabelMapFile(const QString& path);

 protected:
  void dragEnterEvent(QDragEnterEvent* event) override;
  void dropEvent(QDropEvent* event) override;
  void closeEvent(QCloseEvent* event) override;

 private slots:
  void openDialog();
  void about();
  void onRunSucceeded(std::shared_ptr<const femesher::PipelineResult> result);
  void onRunEnded(const QString& state, const QString& message);
  void onSnapshotDrawn(int points);

 private:
  void addRecentFile(const QString& path);
  void updateRecentMenu();
  void scriptStep();
  void finishScript(int code);

  qFEMesherPanelWidget* panel_ = nullptr;
  qFEMesherPreviewView* view_ = nullptr;
  qFEMesherQualityHistogramWidget* histograms_ = nullptr;
  QMenu* recentMenu_ = nullptr;
  Script script_;
  bool scripting_ = false;
  bool midRunShotTaken_ = false;
  int snapshotsDuringRun_ = 0;
  QString sampleDir_;
};
