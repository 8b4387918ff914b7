// SPDX-License-Identifier: GPL-3.0-or-later
#include "qFEMesherMainWindow.h"

#include <qFEMesherPanelWidget.h>
#include <qFEMesherPreviewView.h>
#include <qFEMesherQualityHistogramWidget.h>
#include <qFEMesherRunner.h>

#include <femesher/Phantom.h>
#include <femesher/Version.h>
#include <femesher/io/LabelMapIO.h>

#include <QVTKOpenGLNativeWidget.h>

#include <QAction>
#include <QApplication>
#include <QCloseEvent>
#include <QDir>
#include <QDragEnterEvent>
#include <QDropEvent>
#include <QFileDialog>
#include <QFileInfo>
#include <QMenu>
#include <QMenuBar>
#include <QMessageBox>
#include <QMimeData>
#include <QPainter>
#include <QProgressBar>
#include <QScrollArea>
#include <QSettings>
#include <QSplitter>
#include <QStandardPaths>
#include <QStatusBar>
#include <QTimer>

#include <cstdio>

namespace {
constexpr int kMaxRecent = 8;
}

qFEMesherMainWindow::qFEMesherMainWindow(QWidget* parent) : QMainWindow(parent) {
  setWindowTitle(tr("FEMesher %1").arg(QStringLiteral(FEMESHER_VERSION)));
  setAcceptDrops(true);

  panel_ = new qFEMesherPanelWidget;  // scrolls its own parameters; Run and Cancel stay visible
  panel_->setMinimumWidth(600);

  view_ = new qFEMesherPreviewView;
  histograms_ = new qFEMesherQualityHistogramWidget;

  auto* right = new QSplitter(Qt::Vertical);
  right->addWidget(view_);
  right->addWidget(histograms_);
  right->setStretchFactor(0, 3);
  right->setStretchFactor(1, 2);
  right->setSizes({600, 400});
  auto* split = new QSplitter(Qt::Horizontal);
  split->addWidget(panel_);
  split->addWidget(right);
  split->setStretchFactor(0, 0);
  split->setStretchFactor(1, 1);
  split->setSizes({610, 990});
  setCentralWidget(split);

  // Menus.
  QMenu* file = menuBar()->addMenu(tr("&File"));
  QAction* openAct = file->addAction(tr("&Open segmentation\u2026"), this, &qFEMesherMainWindow::openDialog);
  openAct->setShortcut(QKeySequence::Open);
  file->addAction(tr("Open &sample (femur phantom)"), this, [this] { openSample(); });
  recentMenu_ = file->addMenu(tr("Open &recent"));
  file->addSeparator();
  QAction* shotAct = file->addAction(tr("Save screens&hot\u2026"), this, [this] {
    const QString path = QFileDialog::getSaveFileName(this, tr("Save screenshot"),
                                                      QStringLiteral("femesher.png"),
                                                      tr("PNG image (*.png)"));
    if (!path.isEmpty()) saveScreenshot(path);
  });
  shotAct->setShortcut(QKeySequence(Qt::CTRL | Qt::Key_P));
  file->addSeparator();
  QAction* quit = file->addAction(tr("&Quit"), this, &QWidget::close);
  quit->setShortcut(QKeySequence::Quit);
  QMenu* help = menuBar()->addMenu(tr("&Help"));
  help->addAction(tr("&About FEMesher"), this, &qFEMesherMainWindow::about);
  updateRecentMenu();

  // Wiring: the panel drives the view and the histograms.
  connect(panel_, &qFEMesherPanelWidget::volumeLoaded, this,
          [this](std::shared_ptr<const femesher::LabelVolume> v) {
            view_->setVolume(*v);
            histograms_->clear();
          });
  // A new run keeps the previous result's histograms (the panel keeps its mesh for export) until
  // it succeeds; the view shows the run's live preview meanwhile.
  connect(panel_, &qFEMesherPanelWidget::runStarted, this, [this] {
    view_->setClipping(false);
    view_->setColorBy(qFEMesherPreviewView::ColorBy::Material);
    snapshotsDuringRun_ = 0;
  });
  connect(panel_, &qFEMesherPanelWidget::previewAvailable, view_, &qFEMesherPreviewView::showSnapshot);
  connect(panel_, &qFEMesherPanelWidget::runSucceeded, this, &qFEMesherMainWindow::onRunSucceeded);
  connect(panel_, &qFEMesherPanelWidget::runEnded, this, &qFEMesherMainWindow::onRunEnded);
  connect(panel_, &qFEMesherPanelWidget::statusMessage, this,
          [this](const QString& m) { statusBar()->showMessage(m, 8000); });
  connect(view_, &qFEMesherPreviewView::snapshotDrawn, this, &qFEMesherMainWindow::onSnapshotDrawn);
  connect(view_, &qFEMesherPreviewView::meshShown, histograms_,
          &qFEMesherQualityHistogramWidget::setTetQuality);
  connect(histograms_, &qFEMesherQualityHistogramWidget::showElementRequested, view_,
          [this](long long tet) { view_->showElement(size_t(tet)); });
  statusBar()->showMessage(tr("Open a segmentation (File > Open, or drop a file here), or File > Open sample."));
}

qFEMesherMainWindow::~qFEMesherMainWindow() = default;

bool qFEMesherMainWindow::isLabelMapFile(const QString& path) {
  const QString p = path.toLower();
  for (const char* ext : {".nrrd", ".nhdr", ".nii", ".nii.gz", ".mha", ".mhd"})
    if (p.endsWith(QLatin1String(ext))) return true;
  return false;
}

bool qFEMesherMainWindow::openFile(const QString& path) {
  if (!panel_->openFile(path)) {
    if (!scripting_)
      QMessageBox::warning(this, tr("Cannot open"), panel_->lastError());
    return false;
  }
  setWindowTitle(tr("FEMesher %1 \u2014 %2").arg(QStringLiteral(FEMESHER_VERSION), QFileInfo(path).fileName()));
  addRecentFile(QFileInfo(path).absoluteFilePath());
  return true;
}

bool qFEMesherMainWindow::openSample() {
  if (sampleDir_.isEmpty()) {
    sampleDir_ = QDir(QDir::tempPath()).filePath(
        QStringLiteral("femesher-sample-%1").arg(QCoreApplication::applicationPid()));
    QDir().mkpath(sampleDir_);
  }
  const QString path = QDir(sampleDir_).filePath(QStringLiteral("femur_phantom.nrrd"));
  femesher::LabelVolume phantom = femesher::makePhantom();
  const femesher::Status s = femesher::writeLabelMap(phantom, path.toStdString());
  if (!s) {
    if (!scripting_) QMessageBox::warning(this, tr("Cannot write the sample"), QString::fromStdString(s.message()));
    std::fprintf(stderr, "FEMesherApp: %s\n", s.message().c_str());
    return false;
  }
  return openFile(path);
}

void qFEMesherMainWindow::openDialog() {
  QSettings settings;
  const QString dir = settings.value(QStringLiteral("lastDir")).toString();
  const QString path = QFileDialog::getOpenFileName(
      this, tr("Open segmentation"), dir,
      tr("Label maps (*.nrrd *.nhdr *.nii *.nii.gz *.mha *.mhd *.seg.nrrd);;All files (*)"));
  if (path.isEmpty()) return;
  settings.setValue(QStringLiteral("lastDir"), QFileInfo(path).absolutePath());
  openFile(path);
}

void qFEMesherMainWindow::addRecentFile(const QString& path) {
  if (sampleDir_.size() && path.startsWith(sampleDir_)) return;  // temporary sample file
  QSettings settings;
  QStringList recent = settings.value(QStringLiteral("recentFiles")).toStringList();
  recent.removeAll(path);
  recent.prepend(path);
  while (recent.size() > kMaxRecent) recent.removeLast();
  settings.setValue(QStringLiteral("recentFiles"), recent);
  updateRecentMenu();
}

void qFEMesherMainWindow::updateRecentMenu() {
  recentMenu_->clear();
  const QStringList recent = QSettings().value(QStringLiteral("recentFiles")).toStringList();
  for (const QString& f : recent)
    recentMenu_->addAction(QFileInfo(f).fileName(), this, [this, f] { openFile(f); })->setToolTip(f);
  recentMenu_->setEnabled(!recent.isEmpty());
}

void qFEMesherMainWindow::about() {
  QMessageBox::about(
      this, tr("About FEMesher"),
      tr("<h3>FEMesher %1</h3>"
         "<p>Conformal multi-material tetrahedral meshes from labelled volumes, for finite-element "
         "analysis (particle pipeline with the Integer Medial Axis).</p>"
         "<p>Built with ITK %2, VTK %3, CGAL %4, TetGen %5, Qt %6.</p>"
         "<p>Licence: GPL-3.0-or-later.</p>")
          .arg(QStringLiteral(FEMESHER_VERSION), QStringLiteral(FEMESHER_ITK_VERSION),
               QStringLiteral(FEMESHER_VTK_VERSION), QStringLiteral(FEMESHER_CGAL_VERSION),
               QStringLiteral(FEMESHER_TETGEN_VERSION), QString::fromLatin1(qVersion())));
}

void qFEMesherMainWindow::dragEnterEvent(QDragEnterEvent* event) {
  if (event->mimeData()->hasUrls())
    for (const QUrl& u : event->mimeData()->urls())
      if (u.isLocalFile() && isLabelMapFile(u.toLocalFile())) {
        event->acceptProposedAction();
        return;
      }
}

void qFEMesherMainWindow::dropEvent(QDropEvent* event) {
  for (const QUrl& u : event->mimeData()->urls())
    if (u.isLocalFile() && isLabelMapFile(u.toLocalFile())) {
      openFile(u.toLocalFile());
      event->acceptProposedAction();
      return;
    }
}

void qFEMesherMainWindow::closeEvent(QCloseEvent* event) {
  if (panel_->isRunning()) {
    panel_->runner()->cancel();
    panel_->runner()->wait(-1);
  }
  if (!sampleDir_.isEmpty()) QDir(sampleDir_).removeRecursively();
  event->accept();
}

void qFEMesherMainWindow::onRunSucceeded(std::shared_ptr<const femesher::PipelineResult> result) {
  // Reports first: the view's meshShown (at once for a small mesh) then adds the per-tet values.
  histograms_->setReports(result->quality, result->hasFidelity ? &result->fidelity : nullptr,
                          result->mesh.materials);
  view_->setMesh(std::shared_ptr<const femesher::TetMesh>(result, &result->mesh));
}

// --- screenshots -----------------------------------------------------------------------------------

QImage qFEMesherMainWindow::grabWindowImage(bool settle) {
  if (settle) QApplication::processEvents();
  QImage image = grab().toImage().convertToFormat(QImage::Format_RGB32);
  // QWidget::grab may not include the OpenGL framebuffer (it depends on the platform): paint the
  // render window's own image over its place.
  QImage gl = view_->grabRenderImage();
  if (!gl.isNull()) {
    QPainter p(&image);
    const QPoint at = view_->vtkWidget()->mapTo(this, QPoint(0, 0));
    p.drawImage(QRect(at, view_->vtkWidget()->size()), gl);
  }
  return image;
}

bool qFEMesherMainWindow::saveScreenshot(const QString& path, bool settle) {
  const QImage image = grabWindowImage(settle);
  if (!QFileInfo(path).absoluteDir().exists()) QDir().mkpath(QFileInfo(path).absolutePath());
  const bool ok = !image.isNull() && image.save(path);
  std::fprintf(stderr, "FEMesherApp: %s %s\n", ok ? "saved" : "could not save",
               path.toLocal8Bit().constData());
  return ok;
}

// --- scripted use ------------------------------------------------------------------------------------

void qFEMesherMainWindow::startScript(const Script& script) {
  script_ = script;
  scripting_ = !script.open.isEmpty() || script.sample || script.run || script.exit ||
               !script.screenshot.isEmpty() || !script.screenshotDir.isEmpty();
  if (!scripting_) return;
  QTimer::singleShot(300, this, &qFEMesherMainWindow::scriptStep);
}

void qFEMesherMainWindow::scriptStep() {
  bool ok = true;
  if (script_.sample) ok = openSample();
  else if (!script_.open.isEmpty()) ok = openFile(script_.open);
  if (!ok) {
    std::fprintf(stderr, "FEMesherApp: %s\n", panel_->lastError().toLocal8Bit().constData());
    finishScript(3);
    return;
  }
  if (!script_.parameters.isEmpty() && !panel_->loadParametersFile(script_.parameters)) {
    std::fprintf(stderr, "FEMesherApp: %s\n", panel_->lastError().toLocal8Bit().constData());
    finishScript(2);
    return;
  }
  if (!script_.preset.isEmpty() && !panel_->applyPreset(script_.preset)) {
    std::fprintf(stderr, "FEMesherApp: unknown preset '%s'\n", script_.preset.toLocal8Bit().constData());
    finishScript(2);
    return;
  }
  if (!script_.screenshotDir.isEmpty())
    saveScreenshot(QDir(script_.screenshotDir).filePath(QStringLiteral("01_before_run.png")));
  if (script_.run) {
    midRunShotTaken_ = false;
    if (!panel_->run()) {
      std::fprintf(stderr, "FEMesherApp: %s\n", panel_->lastError().toLocal8Bit().constData());
      finishScript(2);
    }
    return;  // continues in onRunEnded
  }
  if (!script_.screenshot.isEmpty()) saveScreenshot(script_.screenshot);
  if (script_.exit) finishScript(0);
}

void qFEMesherMainWindow::onSnapshotDrawn(int points) {
  ++snapshotsDuringRun_;
  if (!scripting_ || script_.screenshotDir.isEmpty() || midRunShotTaken_) return;
  // The particles once they have spread (a few snapshots into the particle system).
  if (points > 0 && (panel_->progressBar()->value() > 300 || snapshotsDuringRun_ >= 4)) {
    midRunShotTaken_ = true;
    saveScreenshot(QDir(script_.screenshotDir).filePath(QStringLiteral("02_mid_run.png")), false);
  }
}

void qFEMesherMainWindow::onRunEnded(const QString& state, const QString& message) {
  // Canceled or failed: the previous mesh (still the panel's result) comes back into the view.
  if (state != QLatin1String("succeeded") && panel_->result()) view_->restoreMesh();
  if (!scripting_) return;
  if (state != QLatin1String("succeeded")) {
    std::fprintf(stderr, "FEMesherApp: run %s: %s\n", state.toLocal8Bit().constData(),
                 message.toLocal8Bit().constData());
    if (!script_.screenshot.isEmpty()) saveScreenshot(script_.screenshot);
    finishScript(1);
    return;
  }
  int code = 0;
  for (const QString& out : script_.exports)
    if (!panel_->exportMesh(out)) {
      std::fprintf(stderr, "FEMesherApp: %s\n", panel_->lastError().toLocal8Bit().constData());
      code = 4;
    }
  view_->setColorBy(qFEMesherPreviewView::ColorBy::Material);
  view_->setClipping(true, 1, 0.5);
  if (!script_.screenshotDir.isEmpty()) {
    const QDir dir(script_.screenshotDir);
    if (!midRunShotTaken_)
      std::fprintf(stderr, "FEMesherApp: no preview snapshot arrived during the run (02_mid_run.png missing)\n");
    saveScreenshot(dir.filePath(QStringLiteral("03_final_clipped.png")));
    const QImage hist = histograms_->grab().toImage();
    if (!hist.save(dir.filePath(QStringLiteral("04_histograms.png")))) code = 5;
    view_->setColorBy(qFEMesherPreviewView::ColorBy::MinDihedral);
    saveScreenshot(dir.filePath(QStringLiteral("05_quality_coloured.png")));
    view_->setColorBy(qFEMesherPreviewView::ColorBy::Material);
  }
  if (!script_.screenshot.isEmpty() && !saveScreenshot(script_.screenshot)) code = 5;
  if (script_.exit) finishScript(code);
}

void qFEMesherMainWindow::finishScript(int code) {
  if (!script_.exit) return;
  QTimer::singleShot(0, this, [code] { QApplication::exit(code); });
}
