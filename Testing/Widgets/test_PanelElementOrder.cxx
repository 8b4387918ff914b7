// SPDX-License-Identifier: GPL-3.0-or-later
// The panel's element-order switch after a run (issue 15): a phantom meshed at element order 1,
// the order switched to 2, exported as .inp, must hold the mid-edge nodes the CLI writes for the
// same parameters with element_order=2 (same curved nodes, same coordinates within 1e-9), not
// straight-sided ones; the panel says what the export will do, and switching back to 1 exports
// 4-node tets again. A screenshot of the panel after the switch at 1366x768 is saved.
// Runs under xvfb-run (screen 1366x768); the screenshot path is printed.
#include <qFEMesherPanelWidget.h>

#include <femesher/Phantom.h>
#include <femesher/io/LabelMapIO.h>
#include <femesher/io/MeshIO.h>

#include <QDir>
#include <QDoubleSpinBox>
#include <QFile>
#include <QFileInfo>
#include <QGroupBox>
#include <QJsonDocument>
#include <QJsonObject>
#include <QLabel>
#include <QProcess>
#include <QScrollArea>
#include <QtTest>

#include "PanelWait.h"

#include <cmath>

using namespace femesher;

namespace {

/// Mid-edge nodes of `file` farther than 1e-9 mm from their edge's midpoint.
size_t curvedCount(const MeshFile& file) {
  size_t n = 0;
  for (const auto& [key, p] : file.midEdgeNodes) {
    const Vec3& a = file.mesh.points[size_t(key >> 32)];
    const Vec3& b = file.mesh.points[size_t(key & 0xffffffffu)];
    double d2 = 0;
    for (int k = 0; k < 3; ++k) {
      const double d = p[size_t(k)] - 0.5 * (a[size_t(k)] + b[size_t(k)]);
      d2 += d * d;
    }
    n += std::sqrt(d2) > 1e-9;
  }
  return n;
}

}  // namespace

class PanelElementOrderTest : public QObject {
  Q_OBJECT

 private:
  QString tmp_;
  QString phantomPath_;
  std::unique_ptr<qFEMesherPanelWidget> panel_;

  QString tmpFile(const QString& name) const { return QDir(tmp_).filePath(name); }
  QDoubleSpinBox* orderEditor() const {
    return qobject_cast<QDoubleSpinBox*>(panel_->parameterEditor(QStringLiteral("element_order")));
  }
  QString message() const {
    auto* label = panel_->findChild<QLabel*>(QStringLiteral("message"));
    return label ? label->text() : QString();
  }
  bool waitForEnd(int timeoutMs) { return waitForPanelEnd(*panel_, timeoutMs); }

 private slots:
  void initTestCase() {
    tmp_ = QStringLiteral(FEMESHER_TEST_TMP_DIR "/panel_order");
    QDir(tmp_).removeRecursively();
    QVERIFY(QDir().mkpath(tmp_));
    phantomPath_ = tmpFile(QStringLiteral("phantom.nrrd"));
    QVERIFY(writeLabelMap(makePhantom(), phantomPath_.toStdString()).isOk());
    panel_ = std::make_unique<qFEMesherPanelWidget>();
    panel_->resize(1366, 768);
    panel_->show();
    QVERIFY(QTest::qWaitForWindowExposed(panel_.get()));
    QVERIFY2(panel_->openFile(phantomPath_), qPrintable(panel_->lastError()));
    QVERIFY(orderEditor());
    QCOMPARE(int(orderEditor()->value()), 1);
  }

  void switchToOrderTwoAfterARunExportsTheCliNodes() {
    // A run at element order 1, its parameters saved for the CLI.
    const QString params = tmpFile(QStringLiteral("order1.json"));
    QVERIFY2(panel_->saveParametersFile(params), qPrintable(panel_->lastError()));
    QVERIFY(panel_->run());
    QVERIFY(waitForEnd(600000));
    QCOMPARE(panel_->runState(), QStringLiteral("succeeded"));
    QVERIFY(panel_->result());
    QVERIFY(!panel_->result()->midEdgeNodes);  // an order-1 run curves nothing ...
    QVERIFY(panel_->result()->deferredCurving);  // ... but keeps what curving needs
    qInfo("kept for curving: %.2f MB",
          double(panel_->result()->deferredCurving->memoryBytes()) / (1024.0 * 1024.0));

    // The switch: the panel says what the export will write.
    panel_->advancedGroup()->setChecked(true);
    QTest::qWait(50);
    const QString preset = panel_->currentPreset();
    orderEditor()->setValue(2);
    QCOMPARE(panel_->currentPreset(), preset);  // the element order is no part of a preset
    QCOMPARE(panel_->parameters().elementOrder, 2);
    QVERIFY2(message().contains(QStringLiteral("exactly as a run at element order 2")),
             qPrintable(message()));
    panel_->scrollArea()->ensureWidgetVisible(orderEditor());
    QTest::qWait(100);
    QVERIFY(!orderEditor()->visibleRegion().isEmpty());
    const QString shots = QStringLiteral(FEMESHER_SCREENSHOT_DIR);
    QVERIFY(QDir().mkpath(shots));
    const QString shot = QDir(shots).filePath(QStringLiteral("panel_order2_after_run_1366x768.png"));
    QVERIFY(panel_->window()->grab().save(shot));
    qInfo("screenshot: %s", qPrintable(shot));

    // The panel's export at order 2.
    const QString gui = tmpFile(QStringLiteral("gui.inp"));
    QVERIFY2(panel_->exportMesh(gui), qPrintable(panel_->lastError()));
    QVERIFY2(message().contains(QStringLiteral("curved")), qPrintable(message()));

    // The CLI at the same parameters with element_order=2.
    const QString cliOut = tmpFile(QStringLiteral("cli.inp"));
    const QString report = tmpFile(QStringLiteral("cli_report.json"));
    QProcess cli;
    cli.start(QStringLiteral(FEMESHER_CLI),
              {QStringLiteral("mesh"), phantomPath_, QStringLiteral("-o"), cliOut,
               QStringLiteral("--parameters"), params, QStringLiteral("--set"),
               QStringLiteral("element_order=2"), QStringLiteral("--report"), report});
    QVERIFY(cli.waitForFinished(600000));
    QVERIFY2(cli.exitCode() == 0, cli.readAllStandardError().constData());

    auto a = readMeshFile(gui.toStdString());
    auto b = readMeshFile(cliOut.toStdString());
    QVERIFY2(a.isOk(), a.isOk() ? "" : a.status().message().c_str());
    QVERIFY2(b.isOk(), b.isOk() ? "" : b.status().message().c_str());
    const MeshFile& g = a.value();
    const MeshFile& c = b.value();
    QCOMPARE(g.elementOrder, 2);
    QCOMPARE(c.elementOrder, 2);
    // The same corner mesh ...
    QCOMPARE(g.mesh.points.size(), c.mesh.points.size());
    QVERIFY(g.mesh.tets == c.mesh.tets);
    for (size_t i = 0; i < g.mesh.points.size(); ++i)
      for (int k = 0; k < 3; ++k)
        QVERIFY(std::fabs(g.mesh.points[i][size_t(k)] - c.mesh.points[i][size_t(k)]) <= 1e-9);
    // ... with the same mid-edge nodes: as many curved, each where the CLI put it.
    QCOMPARE(g.midEdgeNodes.size(), c.midEdgeNodes.size());
    const size_t curved = curvedCount(c);
    qInfo("%zu mid-edge nodes, %zu curved by the CLI, %zu in the panel's export",
          c.midEdgeNodes.size(), curved, curvedCount(g));
    QVERIFY2(curved > 100, "the CLI curved (almost) nothing: the comparison would prove nothing");
    QCOMPARE(curvedCount(g), curved);
    double worst = 0;
    for (const auto& [key, p] : c.midEdgeNodes) {
      const auto it = g.midEdgeNodes.find(key);
      QVERIFY2(it != g.midEdgeNodes.end(), "an edge of the CLI's mesh has no node in the panel's");
      for (int k = 0; k < 3; ++k) worst = std::max(worst, std::fabs(it->second[size_t(k)] - p[size_t(k)]));
    }
    qInfo("largest coordinate difference %.3g mm", worst);
    QVERIFY(worst <= 1e-9);
    // The figures the panel reports are the CLI's.
    QFile r(report);
    QVERIFY(r.open(QIODevice::ReadOnly));
    const QJsonObject counts = QJsonDocument::fromJson(r.readAll()).object().value("counts").toObject();
    QVERIFY(counts.contains(QStringLiteral("quadratic_curved_nodes")));
    const QuadraticCurvingResult f = panel_->result()->deferredCurving->figures();
    QCOMPARE(double(f.curvedNodes), counts.value(QStringLiteral("quadratic_curved_nodes")).toDouble());
    QCOMPARE(double(f.partlyCurvedNodes),
             counts.value(QStringLiteral("quadratic_partly_curved_nodes")).toDouble());
  }

  void formatsWithoutTenNodeTetsAreRefused() {
    QVERIFY(panel_->applyPreset(QStringLiteral("default")));
    QCOMPARE(panel_->parameters().elementOrder, 2);  // a preset keeps the element order
    QCOMPARE(panel_->currentPreset(), QStringLiteral("default"));
    const QString stl = tmpFile(QStringLiteral("gui.stl"));
    QVERIFY(!panel_->exportMesh(stl));
    QVERIFY(!QFileInfo::exists(stl));
    QVERIFY(!panel_->lastError().isEmpty());
  }

  void switchingBackExportsFourNodeTets() {
    orderEditor()->setValue(1);
    QVERIFY2(message().contains(QStringLiteral("4-node")), qPrintable(message()));
    const QString gui = tmpFile(QStringLiteral("gui_order1.inp"));
    QVERIFY2(panel_->exportMesh(gui), qPrintable(panel_->lastError()));
    auto a = readMeshFile(gui.toStdString());
    QVERIFY(a.isOk());
    QCOMPARE(a.value().elementOrder, 1);
    QCOMPARE(a.value().mesh.tets.size(), panel_->result()->mesh.tets.size());
  }

  void cleanupTestCase() {
    if (panel_->isRunning()) {
      panel_->cancel();
      waitForEnd(60000);
    }
    panel_.reset();
  }
};

QTEST_MAIN(PanelElementOrderTest)
#include "test_PanelElementOrder.moc"
