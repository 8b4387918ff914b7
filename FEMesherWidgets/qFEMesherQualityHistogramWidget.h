// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file qFEMesherQualityHistogramWidget.h
/// Quality at a glance: four QPainter histograms (aspect ratio, radius ratio, minimum dihedral
/// angle, volume) for the whole mesh or one material, each with its bad threshold drawn as a red
/// line and the number of bad tets printed; below them the fidelity table (Dice, volume error per
/// label; boundary distances; missing labels). Pure QWidget painting: works offscreen.

#include <femesher/Types.h>
#include <femesher/stages/Fidelity.h>
#include <femesher/stages/Quality.h>

#include <QWidget>

#include <optional>

class QComboBox;
class QLabel;
class QTableWidget;

/// One histogram drawn with QPainter.
class qFEMesherHistogramPlot : public QWidget {
  Q_OBJECT
 public:
  explicit qFEMesherHistogramPlot(QWidget* parent = nullptr);
  /// `metric` may be null (empty plot with the title).
  void setMetric(const QString& title, const femesher::MetricSummary* metric);
  QString title() const { return title_; }
  bool hasData() const { return hasData_; }
  size_t totalCount() const;
  size_t badCount() const { return metric_.badCount; }
  /// The caption printed under the title, e.g. "12 bad (> 3)".
  QString badText() const;
  QSize sizeHint() const override { return {260, 170}; }
  QSize minimumSizeHint() const override { return {160, 110}; }

 protected:
  void paintEvent(QPaintEvent*) override;

 private:
  QString title_;
  femesher::MetricSummary metric_;
  bool hasData_ = false;
};

class qFEMesherQualityHistogramWidget : public QWidget {
  Q_OBJECT
 public:
  explicit qFEMesherQualityHistogramWidget(QWidget* parent = nullptr);

  /// Show a run's reports. `materials` names and colours the per-material choices.
  void setReports(const femesher::QualityReport& quality, const femesher::FidelityReport* fidelity,
                  const std::vector<femesher::Material>& materials);
  void clear();

  /// Select "All materials" (label = kExteriorLabel) or one material label.
  bool selectMaterial(int32_t label);
  int32_t selectedMaterial() const;

  // For tests and the app.
  QComboBox* materialCombo() const { return combo_; }
  qFEMesherHistogramPlot* plot(int i) const { return plots_[i]; }  ///< 0..3
  static constexpr int plotCount() { return 4; }
  QTableWidget* fidelityTable() const { return fidelity_; }
  QLabel* summaryLabel() const { return summary_; }

 private slots:
  void updatePlots();

 private:
  femesher::QualityReport quality_;
  std::optional<femesher::FidelityReport> fidelityReport_;
  bool hasQuality_ = false;
  QComboBox* combo_ = nullptr;
  qFEMesherHistogramPlot* plots_[4] = {};
  QTableWidget* fidelity_ = nullptr;
  QLabel* summary_ = nullptr;
  QLabel* distances_ = nullptr;
};
