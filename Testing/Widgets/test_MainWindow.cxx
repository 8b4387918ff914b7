// SPDX-License-Identifier: GPL-3.0-or-later
// FEMesherApp's window under a virtual X server: an opened map is drawn as label surfaces (picture
// window_opened_1366x768.png); at 1366x768 with Advanced open, Run, Cancel and
// the progress bar are on screen; a canceled second run gives the view and the histograms back
// the first mesh; and pictures of the window at 1366x768 and 1600x1000 after a phantom run
// (Advanced open, histograms visible) go to $FEMESHER_SHOTS_DIR (default: the test's tmp dir).
#include <qFEMesherMainWindow.h>
#include <qFEMesherPanelWidget.h>
#include <qFEMesherPreviewView.h>
#include <qFEMesherQualityHistogramWidget.h>

#include <QDir>
#include <QDoubleSpinBox>
#include <QGroupBox>
#include <QProgressBar>
#include <QPushButton>
#include <QScrollArea>
#include <QSignalSpy>
#include <QSurfaceFormat>
#include <QVTKOpenGLNativeWidget.h>
#include <QtTest>

#include "PanelWait.h"

class MainWindowTest : public QObject {
  Q_OBJECT
 private:
  std::unique_ptr<qFEMesherMainWindow> window_;

  qFEMesherPanelWidget* panel() const { return window_->panel(); }
  bool waitForEnd(int timeoutMs) { return waitForPanelEnd(*panel(), timeoutMs, 100); }
  static QString shotsDir() {
    QString dir = qEnvironmentVariable("FEMESHER_SHOTS_DIR");
    if (dir.isEmpty()) dir = QStringLiteral(FEMESHER_TEST_TMP_DIR "/mainwindow");
    QDir().mkpath(dir);
    return dir;
  }
  /// The part of `w` that can be seen inside the window (clipped by scroll areas and the window).
  QRect shownRect(QWidget* w) const {
    const QRect inWindow(w->mapTo(window_.get(), QPoint(0, 0)), w->size());
    return w->visibleRegion().boundingRect().translated(inWindow.topLeft()) & window_->rect();
  }

 private slots:
  void initTestCase() {
    window_ = std::make_unique<qFEMesherMainWindow>();
    window_->resize(1366, 768);
    window_->show();
    QVERIFY(QTest::qWaitForWindowExposed(window_.get()));
    QVERIFY2(window_->openSample(), qPrintable(panel()->lastError()));
    // The opened map is drawn as its label surfaces.
    QTRY_VERIFY_WITH_TIMEOUT(!window_->view()->isPreparingInput(), 30000);
    QVERIFY(window_->view()->inputTriangleCount() > 1000);
    QVERIFY(window_->saveScreenshot(QDir(shotsDir()).filePath(QStringLiteral("window_opened_1366x768.png"))));
  }

  void fitsA1366x768ScreenWithAdvancedOpen() {
    panel()->advancedGroup()->setChecked(true);
    QTest::qWait(200);
    QCOMPARE(window_->size(), QSize(1366, 768));  // no minimum size forces a larger window
    const QSize min = window_->minimumSizeHint();
    QVERIFY2(min.width() <= 1366 && min.height() <= 768,
             qPrintable(QString("minimum size %1x%2").arg(min.width()).arg(min.height())));
    // The Advanced section is taller than the space it has: the parameters scroll ...
    QScrollArea* scroll = panel()->scrollArea();
    QVERIFY(scroll->widget()->height() > scroll->viewport()->height());
    // ... and Run, Cancel and the progress bar are wholly inside the window.
    for (QWidget* w : {static_cast<QWidget*>(panel()->runButton()),
                       static_cast<QWidget*>(panel()->cancelButton()),
                       static_cast<QWidget*>(panel()->progressBar())}) {
      QVERIFY(w->isVisible());
      const QRect inWindow(w->mapTo(window_.get(), QPoint(0, 0)), w->size());
      QVERIFY2(window_->rect().contains(inWindow), qPrintable(w->objectName() + w->metaObject()->className()));
      QCOMPARE(shownRect(w), inWindow);
    }
  }

  void canceledRunGivesTheFirstMeshBack() {
    QVERIFY(panel()->applyPreset(QStringLiteral("default")));
    QVERIFY(panel()->run());
    QVERIFY(waitForEnd(300000));
    QCOMPARE(panel()->runState(), QStringLiteral("succeeded"));
    auto first = panel()->result();
    QTRY_VERIFY_WITH_TIMEOUT(window_->view()->content() == qFEMesherPreviewView::Content::Mesh, 60000);
    QCOMPARE(window_->view()->displayedCellCount(), first->mesh.tets.size());
    QCOMPARE(window_->histograms()->plot(0)->totalCount(), first->mesh.tets.size());
    // A long second run, canceled once the live preview replaced the mesh in the view.
    QVERIFY(useLongRun(*panel()));
    QVERIFY(panel()->run());
    QCOMPARE(window_->histograms()->plot(0)->totalCount(), first->mesh.tets.size());
    QVERIFY2(waitWhileRunning(
                 *panel(),
                 [&] { return window_->view()->content() == qFEMesherPreviewView::Content::Preview; },
                 120000),
             "the run ended before it could be canceled");
    panel()->cancel();
    QVERIFY(waitForEnd(60000));
    QCOMPARE(panel()->runState(), QStringLiteral("canceled"));
    QCOMPARE(panel()->result().get(), first.get());
    QCOMPARE(window_->view()->content(), qFEMesherPreviewView::Content::Mesh);
    QCOMPARE(window_->view()->displayedCellCount(), first->mesh.tets.size());
    QCOMPARE(window_->histograms()->plot(0)->totalCount(), first->mesh.tets.size());
    QVERIFY(panel()->applyPreset(QStringLiteral("default")));
  }

  void screenshots() {
    QVERIFY(panel()->result());
    const QString dir = shotsDir();
    panel()->advancedGroup()->setChecked(true);
    window_->view()->setClipping(true, 1, 0.5);
    for (const QSize size : {QSize(1366, 768), QSize(1600, 1000)}) {
      window_->resize(size);
      QTest::qWait(300);
      QCOMPARE(window_->size(), size);
      const QString path = QDir(dir).filePath(
          QStringLiteral("window_%1x%2.png").arg(size.width()).arg(size.height()));
      QVERIFY(window_->saveScreenshot(path));
      QCOMPARE(QImage(path).size(), size);
    }
    // "Show worst" of the minimum dihedral angle: the view outlines that tet.
    qFEMesherQualityHistogramWidget* h = window_->histograms();
    QVERIFY(h->worstElement(2) >= 0);
    h->worstButton(2)->click();
    QCOMPARE(window_->view()->highlightedElement(), h->worstElement(2));
    QVERIFY(window_->saveScreenshot(QDir(dir).filePath(QStringLiteral("window_worst_dihedral_1600x1000.png"))));
    window_->view()->setClipping(false);
  }

  void cleanupTestCase() {
    if (panel()->isRunning()) {
      panel()->cancel();
      waitForEnd(60000);
    }
    window_.reset();
  }
};

int main(int argc, char* argv[]) {
  QSurfaceFormat::setDefaultFormat(QVTKOpenGLNativeWidget::defaultFormat());
  QApplication::setAttribute(Qt::AA_ShareOpenGLContexts);
  QApplication app(argc, argv);
  MainWindowTest test;
  return QTest::qExec(&test, argc, argv);
}
#include "test_MainWindow.moc"
