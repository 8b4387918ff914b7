// SPDX-License-Identifier: GPL-3.0-or-later
// Drives the meshing panel (and the histogram widget wired to it) like a user: open a volume,
// read the material table, change presets and parameters, save/load a parameter file (and give
// it to the CLI), run, cancel mid-run, run to the end, exclude a material, export every format,
// cancel a second run and still export the first mesh; histograms (definitions, log volume, worst
// tets) and the fidelity table's volume tolerance; a material renamed in the table.
// Pure QWidgets: runs with QT_QPA_PLATFORM=offscreen.
#include <qFEMesherPanelWidget.h>
#include <qFEMesherQualityHistogramWidget.h>
#include <qFEMesherRunner.h>

#include <femesher/Phantom.h>
#include <femesher/StageTable.h>
#include <femesher/io/LabelMapIO.h>
#include <femesher/io/MeshIO.h>

#include <QCheckBox>
#include <QComboBox>
#include <QDir>
#include <QDoubleSpinBox>
#include <QFile>
#include <QFileInfo>
#include <QGroupBox>
#include <QLabel>
#include <QListWidget>
#include <QProcess>
#include <QProgressBar>
#include <QPushButton>
#include <QSignalSpy>
#include <QTableWidget>
#include <QtTest>

#include "PanelWait.h"

#include <set>

using namespace femesher;

class PanelWidgetTest : public QObject {
  Q_OBJECT

 private:
  QString tmp_;
  QString phantomPath_;
  std::unique_ptr<qFEMesherPanelWidget> panel_;
  std::unique_ptr<qFEMesherQualityHistogramWidget> histograms_;

  QString tmpFile(const QString& name) const { return QDir(tmp_).filePath(name); }
  /// Whether the progress signals recorded so far name `stage`.
  static bool reached(const QSignalSpy& progress, const QString& stage) {
    for (const auto& args : progress)
      if (args.at(0).toString() == stage) return true;
    return false;
  }
  QDoubleSpinBox* spin(const char* key) const {
    return qobject_cast<QDoubleSpinBox*>(panel_->parameterEditor(QString::fromLatin1(key)));
  }
  bool waitForEnd(int timeoutMs) { return waitForPanelEnd(*panel_, timeoutMs); }

 private slots:
  void initTestCase() {
    tmp_ = QStringLiteral(FEMESHER_TEST_TMP_DIR "/panel");
    QDir(tmp_).removeRecursively();
    QVERIFY(QDir().mkpath(tmp_));
    phantomPath_ = tmpFile(QStringLiteral("phantom.nrrd"));
    QVERIFY(writeLabelMap(makePhantom(), phantomPath_.toStdString()).isOk());
    panel_ = std::make_unique<qFEMesherPanelWidget>();
    histograms_ = std::make_unique<qFEMesherQualityHistogramWidget>();
    connect(panel_.get(), &qFEMesherPanelWidget::runSucceeded, histograms_.get(),
            [this](std::shared_ptr<const PipelineResult> r) {
              histograms_->setReports(r->quality, r->hasFidelity ? &r->fidelity : nullptr,
                                      r->mesh.materials);
            });
    panel_->resize(600, 1000);
    panel_->show();
  }

  void everyStageHasAHumanName() {
    for (const StageInfo& s : stageTable()) {
      const QString key = QString::fromLatin1(s.key);
      const QString title = qFEMesherPanelWidget::stageTitle(key);
      QVERIFY2(!title.isEmpty() && title != key && title.contains(QLatin1Char(' ')), s.key);
    }
  }

  void beforeOpeningNothingRuns() {
    QVERIFY(!panel_->runButton()->isEnabled());
    QVERIFY(!panel_->run());
    QVERIFY(!panel_->lastError().isEmpty());
    for (const QString& ext : panel_->exportExtensions())
      QVERIFY(!panel_->exportButton(ext)->isEnabled());
  }

  void openFileFillsMaterialTable() {
    QSignalSpy loaded(panel_.get(), &qFEMesherPanelWidget::volumeLoaded);
    QVERIFY2(panel_->openFile(phantomPath_), qPrintable(panel_->lastError()));
    QCOMPARE(loaded.count(), 1);
    const LabelVolume v = readLabelMap(phantomPath_.toStdString()).value();
    const LabelMapSummary summary = summarizeLabelMap(v);
    QTableWidget* t = panel_->materialTable();
    QCOMPARE(t->rowCount(), 5);
    int checked = 0;
    for (const auto& s : summary.labels) {
      if (s.id == 0) continue;
      const int row = panel_->materialRow(s.id);
      QVERIFY2(row >= 0, qPrintable(QString("label %1 not in the table").arg(s.id)));
      QCOMPARE(t->item(row, qFEMesherPanelWidget::ColId)->text().toInt(), s.id);
      QCOMPARE(t->item(row, qFEMesherPanelWidget::ColVoxels)->data(Qt::DisplayRole).toULongLong(),
               qulonglong(s.voxels));
      const QColor c = t->item(row, qFEMesherPanelWidget::ColColor)->data(Qt::UserRole).value<QColor>();
      const Material* m = findMaterial(v.materials, s.id);
      QVERIFY(m);
      QVERIFY(std::abs(c.redF() - m->color[0]) < 0.01 && std::abs(c.greenF() - m->color[1]) < 0.01 &&
              std::abs(c.blueF() - m->color[2]) < 0.01);
      QCOMPARE(t->item(row, qFEMesherPanelWidget::ColName)->text(), QString::fromStdString(m->name));
      checked += panel_->isMaterialIncluded(s.id);
    }
    QCOMPARE(checked, 5);
    QVERIFY(panel_->runButton()->isEnabled());
  }

  void openingABadFileKeepsTheVolume() {
    auto before = panel_->volume();
    const QString missing = tmpFile(QStringLiteral("does_not_exist.nrrd"));
    QVERIFY(!panel_->openFile(missing));
    QVERIFY2(panel_->lastError().contains(QStringLiteral("does_not_exist.nrrd")),
             qPrintable(panel_->lastError()));
    QCOMPARE(panel_->volume().get(), before.get());
    QCOMPARE(panel_->materialTable()->rowCount(), 5);
  }

  void presetsAndParameters() {
    QVERIFY(panel_->applyPreset(QStringLiteral("coarse")));
    QCOMPARE(panel_->currentPreset(), QStringLiteral("coarse"));
    QCOMPARE(spin("edge_length_factor")->value(), presetParameters("coarse")->sizing.edgeLengthFactor);
    QCOMPARE(panel_->parameters().sizing.edgeLengthFactor, presetParameters("coarse")->sizing.edgeLengthFactor);
    QVERIFY(panel_->applyPreset(QStringLiteral("fine")));
    QCOMPARE(panel_->parameters().sizing.edgeLengthFactor, presetParameters("fine")->sizing.edgeLengthFactor);
    QVERIFY(!panel_->applyPreset(QStringLiteral("ultra")));
    // Editing a value switches to Custom and lands in the struct.
    spin("smoothing_sigma")->setValue(1.25);
    QCOMPARE(panel_->currentPreset(), QStringLiteral("custom"));
    QCOMPARE(panel_->parameters().indicators.sigma, 1.25);
    spin("target_edge_length")->setValue(2.5);
    QCOMPARE(panel_->parameters().sizing.targetEdgeLength, 2.5);
    QCOMPARE(spin("target_edge_length")->suffix(), QStringLiteral(" mm"));
    // The automatic sizes read "Automatic" at 0, not "0.00 mm".
    for (const char* key : {"h_min", "h_max"}) {
      QCOMPARE(spin(key)->value(), 0.0);
      QCOMPARE(spin(key)->text(), QStringLiteral("Automatic"));
    }
    // Every descriptor has an editor with its help as tooltip; advanced ones sit in the group.
    for (const auto& d : parameterDescriptors()) {
      QWidget* e = panel_->parameterEditor(QString::fromStdString(d.key));
      QVERIFY2(e, d.key.c_str());
      QVERIFY2(e->toolTip().contains(QString::fromStdString(d.help).toHtmlEscaped().left(20)), d.key.c_str());
      if (d.key == "particle_iterations")
        QVERIFY(panel_->advancedGroup()->isAncestorOf(e));
      if (d.key == "target_edge_length")
        QVERIFY(!panel_->advancedGroup()->isAncestorOf(e));
    }
    // Back to the default preset.
    QVERIFY(panel_->applyPreset(QStringLiteral("default")));
    QCOMPARE(panel_->currentPreset(), QStringLiteral("default"));
    QCOMPARE(parametersToJson(panel_->parameters()), parametersToJson(MeshingParameters{}));
  }

  void materialPropertiesGoIntoParameters() {
    QTableWidget* t = panel_->materialTable();
    const int row = panel_->materialRow(2);
    auto* e = qobject_cast<QDoubleSpinBox*>(t->cellWidget(row, qFEMesherPanelWidget::ColE));
    auto* nu = qobject_cast<QDoubleSpinBox*>(t->cellWidget(row, qFEMesherPanelWidget::ColNu));
    QVERIFY(e && nu);
    e->setValue(12345.0);
    nu->setValue(0.21);
    const MeshingParameters p = panel_->parameters();
    QCOMPARE(p.materialProperties.size(), size_t(1));
    QCOMPARE(p.materialProperties.at(2).youngsModulus, 12345.0);
    QCOMPARE(p.materialProperties.at(2).poissonRatio, 0.21);
  }

  void saveAndLoadParametersThatTheCliAccepts() {
    spin("smoothing_sigma")->setValue(0.6);
    spin("min_voxels")->setValue(20);
    const std::string saved = parametersToJson(panel_->parameters());
    const QString file = tmpFile(QStringLiteral("params.json"));
    QVERIFY2(panel_->saveParametersFile(file), qPrintable(panel_->lastError()));
    panel_->setParameters(MeshingParameters{});
    QVERIFY(parametersToJson(panel_->parameters()) != saved);
    QVERIFY2(panel_->loadParametersFile(file), qPrintable(panel_->lastError()));
    QCOMPARE(QString::fromStdString(parametersToJson(panel_->parameters())), QString::fromStdString(saved));
    // A broken file is refused with a message naming it.
    const QString broken = tmpFile(QStringLiteral("broken.json"));
    {
      QFile f(broken);
      QVERIFY(f.open(QIODevice::WriteOnly));
      f.write("{\"smoothing_sigma\": \"lots\"}");
    }
    QVERIFY(!panel_->loadParametersFile(broken));
    QVERIFY(panel_->lastError().contains(QStringLiteral("broken.json")));
    QCOMPARE(QString::fromStdString(parametersToJson(panel_->parameters())), QString::fromStdString(saved));
    // The CLI reads the same file.
    QProcess cli;
    const QString out = tmpFile(QStringLiteral("cli.vtu"));
    cli.start(QStringLiteral(FEMESHER_CLI),
              {QStringLiteral("mesh"), phantomPath_, QStringLiteral("-o"), out,
               QStringLiteral("--parameters"), file, QStringLiteral("--set"), QStringLiteral("edge_length_factor=3")});
    QVERIFY(cli.waitForFinished(300000));
    QVERIFY2(cli.exitCode() == 0, cli.readAllStandardError().constData());
    QVERIFY(QFileInfo::exists(out));
    QVERIFY(panel_->applyPreset(QStringLiteral("default")));
  }

  void cancelMidRun() {
    QVERIFY(useLongRun(*panel_));
    QSignalSpy progress(panel_.get(), &qFEMesherPanelWidget::progressChanged);
    QSignalSpy ended(panel_.get(), &qFEMesherPanelWidget::runEnded);
    QVERIFY(panel_->run());
    QCOMPARE(panel_->runState(), QStringLiteral("running"));
    QVERIFY(!panel_->runButton()->isEnabled());
    QVERIFY(panel_->cancelButton()->isEnabled());
    // Wait until the particle system runs (the GUI keeps processing events meanwhile; every
    // stage the run enters is forwarded).
    QVERIFY2(waitWhileRunning(*panel_, [&] { return reached(progress, QStringLiteral("ParticleSystem")); },
                              120000),
             "the run ended before it could be canceled");
    QVERIFY(panel_->progressBar()->format().contains(
        qFEMesherPanelWidget::stageTitle(QStringLiteral("ParticleSystem"))));
    panel_->cancel();
    QVERIFY(waitForEnd(60000));
    QCOMPARE(ended.count(), 1);
    QCOMPARE(ended.at(0).at(0).toString(), QStringLiteral("canceled"));
    QCOMPARE(panel_->runState(), QStringLiteral("canceled"));
    QVERIFY(!panel_->result());
    const double latency = panel_->runner()->lastCancelLatency();
    qInfo("cancel took %.3f s", latency);
    QVERIFY(latency >= 0);
    if (latency > 1.0) qWarning("cancel took longer than a second (%.2f s)", latency);
    QVERIFY(panel_->runButton()->isEnabled());
    for (const QString& ext : panel_->exportExtensions())
      QVERIFY(!panel_->exportButton(ext)->isEnabled());
    QVERIFY(!panel_->exportMesh(tmpFile(QStringLiteral("nothing.vtu"))));
    QVERIFY(!QFileInfo::exists(tmpFile(QStringLiteral("nothing.vtu"))));
  }

  void runToTheEndShowsQualityAndFidelity() {
    QVERIFY(panel_->applyPreset(QStringLiteral("default")));
    QSignalSpy succeeded(panel_.get(), &qFEMesherPanelWidget::runSucceeded);
    QSignalSpy progress(panel_.get(), &qFEMesherPanelWidget::progressChanged);
    QVERIFY(panel_->run());
    QVERIFY(waitForEnd(300000));
    QCOMPARE(panel_->runState(), QStringLiteral("succeeded"));
    QCOMPARE(succeeded.count(), 1);
    // Every stage the run went through reached the GUI, in run order (the runner coalesces the
    // progress within a stage, never a stage), is in the stage table and has a name in words in
    // the progress bar.
    QSet<QString> stages;
    QStringList order;
    for (const auto& args : progress) {
      const QString stage = args.at(0).toString();
      stages.insert(stage);
      if (order.isEmpty() || order.back() != stage) order.push_back(stage);
    }
    QVERIFY(!stages.isEmpty());
    QStringList ran;
    for (const auto& t : panel_->result()->timings) ran.push_back(QString::fromStdString(t.name));
    QCOMPARE(order, ran);
    for (const QString& stage : stages) {
      QVERIFY2(findStage(stage.toStdString()), qPrintable(stage));
      const QString title = qFEMesherPanelWidget::stageTitle(stage);
      QVERIFY2(title != stage && title.contains(QLatin1Char(' ')), qPrintable(stage));
    }
    auto r = panel_->result();
    QVERIFY(r);
    QVERIFY(r->mesh.tets.size() > 100);
    std::set<int32_t> labels(r->mesh.tetLabels.begin(), r->mesh.tetLabels.end());
    QCOMPARE(labels, (std::set<int32_t>{1, 2, 3, 4, 5}));
    QCOMPARE(panel_->progressBar()->value(), panel_->progressBar()->maximum());
    QVERIFY(panel_->warningsList()->count() >= int(r->warnings.size()));
    // Tets below min_dihedral_warning: the element check's warning comes first, in bold.
    const QListWidget* warnings = panel_->warningsList();
    int poorItems = 0;
    for (int i = 0; i < warnings->count(); ++i)
      poorItems += warnings->item(i)->text().startsWith(QStringLiteral("Poor elements: "));
    QCOMPARE(poorItems, r->meshCheck.poor() ? 1 : 0);
    if (r->meshCheck.poor()) {
      QCOMPARE(warnings->item(0)->text(),
               QString::fromStdString(femesher::poorElementsWarning(r->meshCheck)));
      QVERIFY(warnings->item(0)->font().bold());
    }
    for (const QString& ext : panel_->exportExtensions())
      QVERIFY(panel_->exportButton(ext)->isEnabled());

    // Histograms: "All materials" + one entry per material; counts add up to the tets.
    QCOMPARE(histograms_->materialCombo()->count(), 1 + int(r->quality.perMaterial.size()));
    QCOMPARE(histograms_->selectedMaterial(), kExteriorLabel);
    for (int i = 0; i < qFEMesherQualityHistogramWidget::plotCount(); ++i) {
      QVERIFY(histograms_->plot(i)->hasData());
      QCOMPARE(histograms_->plot(i)->totalCount(), r->mesh.tets.size());
    }
    const MetricSummary* aspect = r->quality.all.find("aspect_ratio");
    QVERIFY(aspect);
    QCOMPARE(histograms_->plot(0)->badCount(), aspect->badCount);
    QVERIFY(histograms_->plot(0)->badText().startsWith(QString::number(aspect->badCount)));
    // Per material.
    for (const auto& pm : r->quality.perMaterial) {
      QVERIFY(histograms_->selectMaterial(pm.label));
      QCOMPARE(histograms_->plot(0)->totalCount(), pm.tets);
      QCOMPARE(histograms_->plot(2)->badCount(), pm.find("min_dihedral")->badCount);
    }
    QVERIFY(histograms_->selectMaterial(kExteriorLabel));
    // Fidelity table: one row per material, tets add up, Dice as reported.
    QVERIFY(r->hasFidelity);
    QTableWidget* f = histograms_->fidelityTable();
    QCOMPARE(f->rowCount(), int(r->fidelity.materials.size()));
    size_t tets = 0;
    for (int row = 0; row < f->rowCount(); ++row) {
      tets += f->item(row, 2)->text().toULongLong();
      QCOMPARE(f->item(row, 3)->text(), QString::number(r->fidelity.materials[size_t(row)].dice, 'f', 4));
    }
    QCOMPARE(tets, r->mesh.tets.size());
    // Paint once offscreen (exercises the QPainter code) and check it is not blank.
    histograms_->resize(900, 500);
    const QImage img = histograms_->grab().toImage();
    QSet<QRgb> colours;
    for (int y = 0; y < img.height(); y += 3)
      for (int x = 0; x < img.width(); x += 3) colours.insert(img.pixel(x, y));
    QVERIFY(colours.size() > 10);
  }

  void histogramsDefineMetricsAndFindTheWorst() {
    auto r = panel_->result();
    QVERIFY(r);
    const auto mesh = std::shared_ptr<const TetMesh>(r, &r->mesh);
    const auto q = std::make_shared<const TetQuality>(computeTetQuality(r->mesh));
    histograms_->setTetQuality(mesh, q);
    QCOMPARE(qFEMesherQualityHistogramWidget::plotCount(), 5);
    QCOMPARE(histograms_->plot(4)->objectName(), QStringLiteral("scaled_jacobian"));
    QCOMPARE(histograms_->plot(4)->totalCount(), r->mesh.tets.size());
    // Definitions as tooltips.
    const char* words[5] = {"longest edge", "circumradius", "70.5", "logarithmic", "Jacobian"};
    for (int i = 0; i < 5; ++i) {
      QVERIFY2(qFEMesherQualityHistogramWidget::metricDefinition(i).contains(QLatin1String(words[i])), words[i]);
      QVERIFY(histograms_->plot(i)->toolTip().startsWith(qFEMesherQualityHistogramWidget::metricDefinition(i)));
    }
    // The dihedral axis ends at 90 degrees; volumes have log-spaced bins holding every tet.
    QCOMPARE(histograms_->plot(2)->displayLow(), 0.0);
    QCOMPARE(histograms_->plot(2)->displayHigh(), 90.0);
    qFEMesherHistogramPlot* volume = histograms_->plot(3);
    QVERIFY(volume->isLogScale());
    QCOMPARE(volume->totalCount(), r->mesh.tets.size());
    const auto& e = volume->histogram().edges;
    QVERIFY(e.size() > 10);
    QVERIFY(std::abs(std::log(e[2] / e[1]) - std::log(e[9] / e[8])) < 1e-9);
    QVERIFY(e.back() / e.front() > 10);
    // The worst tet of each metric, whole mesh and one material; the button asks for it.
    auto check = [&](int32_t label) {
      const std::vector<double>* values[5] = {&q->aspectRatio, &q->radiusRatio, &q->minDihedral,
                                              &q->volume, &q->scaledJacobian};
      const bool largestIsWorst[5] = {true, true, false, false, false};
      for (int i = 0; i < 5; ++i) {
        double worst = largestIsWorst[i] ? -1e300 : 1e300;
        for (size_t t = 0; t < r->mesh.tets.size(); ++t)
          if (label == kExteriorLabel || r->mesh.tetLabels[t] == label)
            worst = largestIsWorst[i] ? std::max(worst, (*values[i])[t]) : std::min(worst, (*values[i])[t]);
        const long long w = histograms_->worstElement(i);
        QVERIFY(w >= 0);
        QCOMPARE((*values[i])[size_t(w)], worst);
        if (label != kExteriorLabel) QCOMPARE(r->mesh.tetLabels[size_t(w)], label);
      }
    };
    check(kExteriorLabel);
    QVERIFY(histograms_->selectMaterial(2));
    check(2);
    QSignalSpy asked(histograms_.get(), &qFEMesherQualityHistogramWidget::showElementRequested);
    histograms_->worstButton(2)->click();
    QCOMPARE(asked.count(), 1);
    QCOMPARE(asked.at(0).at(0).toLongLong(), histograms_->worstElement(2));
    QVERIFY(histograms_->selectMaterial(kExteriorLabel));
  }

  void fidelityFlagsAVolumeChangeAboveTheTolerance() {
    auto r = panel_->result();
    QVERIFY(r && r->hasFidelity);
    QTableWidget* f = histograms_->fidelityTable();
    for (int c = 0; c < f->columnCount(); ++c)
      QVERIFY(!f->horizontalHeaderItem(c)->toolTip().isEmpty());
    QVERIFY(f->horizontalHeaderItem(4)->toolTip().contains(QStringLiteral("amount only")));
    QVERIFY(histograms_->fidelityNote()->text().contains(QStringLiteral("Dice")));
    QDoubleSpinBox* tol = histograms_->volumeToleranceSpin();
    QCOMPARE(tol->value(), 5.0);
    // The label whose volume changed most; a tolerance below its change flags it (and only the
    // labels beyond the tolerance), one above it says ok.
    size_t worst = 0;
    for (size_t i = 0; i < r->fidelity.materials.size(); ++i)
      if (std::abs(r->fidelity.materials[i].volumeError) > std::abs(r->fidelity.materials[worst].volumeError))
        worst = i;
    const double change = 100.0 * std::abs(r->fidelity.materials[worst].volumeError);
    QVERIFY2(change > 0.05, "no label changed volume: nothing to flag");
    tol->setValue(std::max(0.01, change / 2));
    for (int row = 0; row < f->rowCount(); ++row) {
      const auto& m = r->fidelity.materials[size_t(row)];
      const QString status = f->item(row, 5)->text();
      if (m.dice < 0.8) continue;
      if (100.0 * std::abs(m.volumeError) > tol->value())
        QVERIFY2(status.startsWith(QStringLiteral("volume ")), qPrintable(status));
      else
        QCOMPARE(status, QStringLiteral("ok"));
    }
    QVERIFY(f->item(int(worst), 5)->text().startsWith(QStringLiteral("volume ")));
    tol->setValue(change * 2 + 1);
    QCOMPARE(f->item(int(worst), 5)->text(), QStringLiteral("ok"));
    tol->setValue(5.0);
  }

  void exportEveryFormat() {
    auto r = panel_->result();
    QVERIFY(r);
    QSignalSpy exported(panel_.get(), &qFEMesherPanelWidget::meshExported);
    const QStringList exts = panel_->exportExtensions();
    QVERIFY(exts.size() >= 6);
    for (const QString& ext : exts) {
      const QString path = tmpFile(QStringLiteral("mesh") + ext);
      QVERIFY2(panel_->exportMesh(path), qPrintable(panel_->lastError()));
      QVERIFY(QFileInfo(path).size() > 100);
    }
    QCOMPARE(exported.count(), exts.size());
    // Round trip of the VTU; Young's modulus of label 2 in the INP.
    auto back = readMesh(tmpFile(QStringLiteral("mesh.vtu")).toStdString());
    QVERIFY2(back.isOk(), back.status().message().c_str());
    QCOMPARE(back->tets.size(), r->mesh.tets.size());
    QFile inp(tmpFile(QStringLiteral("mesh.inp")));
    QVERIFY(inp.open(QIODevice::ReadOnly));
    const QByteArray text = inp.readAll();
    QVERIFY2(text.contains("12345"), "material.2.E from the table is not in the INP");
    // An unknown extension is refused and nothing is written.
    QVERIFY(!panel_->exportMesh(tmpFile(QStringLiteral("mesh.xyz"))));
    QVERIFY(!QFileInfo::exists(tmpFile(QStringLiteral("mesh.xyz"))));
  }

  void cancelKeepsThePreviousResult() {
    // Issue 15: a good mesh, then a second run canceled midway: the first mesh is still the
    // result, exportable during and after the canceled run, and the export is that mesh.
    auto first = panel_->result();
    QVERIFY(first);
    const QString before = tmpFile(QStringLiteral("first.mesh"));
    QVERIFY2(panel_->exportMesh(before), qPrintable(panel_->lastError()));
    QVERIFY(useLongRun(*panel_));
    QSignalSpy progress(panel_.get(), &qFEMesherPanelWidget::progressChanged);
    QSignalSpy ended(panel_.get(), &qFEMesherPanelWidget::runEnded);
    QVERIFY(panel_->run());
    QCOMPARE(panel_->result().get(), first.get());
    for (const QString& ext : panel_->exportExtensions())
      QVERIFY2(panel_->exportButton(ext)->isEnabled(), qPrintable(ext));
    QVERIFY2(waitWhileRunning(*panel_, [&] { return reached(progress, QStringLiteral("ParticleSystem")); },
                              120000),
             "the run ended before it could be canceled");
    const QString during = tmpFile(QStringLiteral("during.mesh"));
    QVERIFY2(panel_->exportMesh(during), qPrintable(panel_->lastError()));
    panel_->cancel();
    QVERIFY(waitForEnd(60000));
    QCOMPARE(ended.count(), 1);
    QCOMPARE(ended.at(0).at(0).toString(), QStringLiteral("canceled"));
    QVERIFY2(ended.at(0).at(1).toString().contains(QStringLiteral("previous mesh")),
             qPrintable(ended.at(0).at(1).toString()));
    QCOMPARE(panel_->result().get(), first.get());
    for (const QString& ext : panel_->exportExtensions())
      QVERIFY2(panel_->exportButton(ext)->isEnabled(), qPrintable(ext));
    const QString after = tmpFile(QStringLiteral("after.mesh"));
    QVERIFY2(panel_->exportMesh(after), qPrintable(panel_->lastError()));
    auto bytes = [](const QString& path) {
      QFile f(path);
      return f.open(QIODevice::ReadOnly) ? f.readAll() : QByteArray();
    };
    const QByteArray firstBytes = bytes(before);
    QVERIFY(firstBytes.size() > 1000);
    QVERIFY2(bytes(after) == firstBytes, "the export after the canceled run is not the first mesh");
    QVERIFY2(bytes(during) == firstBytes, "the export during the run is not the first mesh");
    auto back = readMesh(after.toStdString());
    QVERIFY2(back.isOk(), back.status().message().c_str());
    QCOMPARE(back->tets.size(), first->mesh.tets.size());
    QVERIFY(panel_->applyPreset(QStringLiteral("default")));
  }

  void excludedMaterialIsNotMeshed() {
    panel_->setMaterialIncluded(5, false);
    QVERIFY(!panel_->isMaterialIncluded(5));
    // The exclusion is a parameter: the loaded volume itself is untouched.
    QCOMPARE(panel_->parameters().preprocess.excluded.size(), size_t(1));
    QVERIFY(panel_->parameters().preprocess.excluded.at(5) == Exclusion::Background);
    QVERIFY(std::find(panel_->volume()->labels.begin(), panel_->volume()->labels.end(), 5) !=
            panel_->volume()->labels.end());
    QVERIFY(panel_->run());
    QVERIFY(waitForEnd(300000));
    QCOMPARE(panel_->runState(), QStringLiteral("succeeded"));
    std::set<int32_t> labels(panel_->result()->mesh.tetLabels.begin(),
                             panel_->result()->mesh.tetLabels.end());
    QCOMPARE(labels, (std::set<int32_t>{1, 2, 3, 4}));
    panel_->setMaterialIncluded(5, true);
    QVERIFY(panel_->parameters().preprocess.excluded.empty());
    // All unticked: refused with a message.
    for (int32_t id = 1; id <= 5; ++id) panel_->setMaterialIncluded(id, false);
    QVERIFY(!panel_->run());
    QVERIFY(panel_->lastError().contains(QStringLiteral("tick")));
    for (int32_t id = 1; id <= 5; ++id) panel_->setMaterialIncluded(id, true);
  }

  void savedExclusionsReproduceTheGuiMeshFromTheCli() {
    // Label 5 merged into its neighbour, label 4 cut away; the GUI's mesh, then the CLI's with the
    // panel's parameter file: the same bytes.
    panel_->setMaterialIncluded(5, false);
    panel_->setMaterialExclusion(5, Exclusion::MergeIntoNeighbour);
    panel_->setMaterialIncluded(4, false);
    panel_->setMaterialExclusion(4, Exclusion::Background);
    // A material renamed in the table: material.2.name, in the mesh and the parameter file.
    QTableWidgetItem* name2 = panel_->materialTable()->item(panel_->materialRow(2), qFEMesherPanelWidget::ColName);
    QVERIFY(name2->flags() & Qt::ItemIsEditable);
    const QString mapName = name2->text();
    name2->setText(QStringLiteral("spongy bone"));
    QCOMPARE(panel_->parameters().preprocess.names.at(2), std::string("spongy bone"));
    QCOMPARE(panel_->parameters().preprocess.names.count(1), size_t(0));
    const QString params = tmpFile(QStringLiteral("excluded.json"));
    QVERIFY2(panel_->saveParametersFile(params), qPrintable(panel_->lastError()));
    QVERIFY(panel_->run());
    QVERIFY(waitForEnd(300000));
    QCOMPARE(panel_->runState(), QStringLiteral("succeeded"));
    std::set<int32_t> labels(panel_->result()->mesh.tetLabels.begin(),
                             panel_->result()->mesh.tetLabels.end());
    QCOMPARE(labels, (std::set<int32_t>{1, 2, 3}));
    const Material* renamed = findMaterial(panel_->result()->mesh.materials, 2);
    QVERIFY(renamed);
    QCOMPARE(renamed->name, std::string("spongy bone"));
    bool mergedNamed = false;
    for (const auto& w : panel_->result()->warnings)
      mergedNamed |= w.find("merged into its neighbours") != std::string::npos;
    QVERIFY2(mergedNamed, "no warning says where label 5 went");
    const QString gui = tmpFile(QStringLiteral("gui.mesh"));
    QVERIFY2(panel_->exportMesh(gui), qPrintable(panel_->lastError()));
    QProcess cli;
    const QString out = tmpFile(QStringLiteral("cli.mesh"));
    cli.start(QStringLiteral(FEMESHER_CLI), {QStringLiteral("mesh"), phantomPath_,
                                             QStringLiteral("-o"), out,
                                             QStringLiteral("--parameters"), params});
    QVERIFY(cli.waitForFinished(300000));
    QVERIFY2(cli.exitCode() == 0, cli.readAllStandardError().constData());
    QFile a(gui), b(out);
    QVERIFY(a.open(QIODevice::ReadOnly) && b.open(QIODevice::ReadOnly));
    const QByteArray guiBytes = a.readAll(), cliBytes = b.readAll();
    QVERIFY(guiBytes.size() > 1000);
    QVERIFY2(guiBytes == cliBytes, "the CLI with the panel's parameter file made another mesh");
    // Loading the file back restores the ticks and the choices.
    panel_->setMaterialIncluded(4, true);
    panel_->setMaterialIncluded(5, true);
    QVERIFY2(panel_->loadParametersFile(params), qPrintable(panel_->lastError()));
    QVERIFY(!panel_->isMaterialIncluded(4) && !panel_->isMaterialIncluded(5));
    QVERIFY(panel_->materialExclusion(5) == Exclusion::MergeIntoNeighbour);
    QVERIFY(panel_->materialExclusion(4) == Exclusion::Background);
    QCOMPARE(name2->text(), QStringLiteral("spongy bone"));
    panel_->setParameters(MeshingParameters{});
    QCOMPARE(name2->text(), mapName);  // no name given: the label map's
    QVERIFY(panel_->parameters().preprocess.names.empty());
    panel_->setMaterialIncluded(4, true);
    panel_->setMaterialIncluded(5, true);
  }

  void sizeOutOfRangeForTheVolumeIsAnErrorNotAHang() {
    // Issue 14, item 5: the panel's smallest target_edge_length step (0.01 mm) on the phantom's
    // 1 mm voxels asks for about 1e11 tets. The run fails at once with the parameter, the
    // smallest useful value and a remedy; no stage runs and the previous result stays.
    auto previous = panel_->result();
    const MeshingParameters before = panel_->parameters();
    MeshingParameters p = before;
    p.sizing.targetEdgeLength = 0.01;
    panel_->setParameters(p);
    QCOMPARE(panel_->parameters().sizing.targetEdgeLength, 0.01);
    QSignalSpy progress(panel_.get(), &qFEMesherPanelWidget::progressChanged);
    QSignalSpy ended(panel_.get(), &qFEMesherPanelWidget::runEnded);
    QVERIFY(panel_->run());
    if (!waitForEnd(60000)) {
      panel_->cancel();
      waitForEnd(60000);
      QFAIL("the run did not end within 60 s");
    }
    QCOMPARE(ended.count(), 1);
    QCOMPARE(ended.at(0).at(0).toString(), QStringLiteral("failed"));
    const QString message = ended.at(0).at(1).toString();
    QVERIFY2(message.contains(QStringLiteral("target_edge_length = 0.01 mm")) &&
                 message.contains(QStringLiteral("smallest useful value")) &&
                 message.contains(QStringLiteral("Use a value >=")),
             qPrintable(message));
    QVERIFY2(!reached(progress, QStringLiteral("IndicatorFunctions")), "a stage ran");
    QCOMPARE(panel_->result().get(), previous.get());
    panel_->setParameters(before);
  }

  void cleanupTestCase() {
    if (panel_->isRunning()) {
      panel_->cancel();
      waitForEnd(60000);
    }
    panel_.reset();
    histograms_.reset();
  }
};

QTEST_MAIN(PanelWidgetTest)
#include "test_PanelWidget.moc"
