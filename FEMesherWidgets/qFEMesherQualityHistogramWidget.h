// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file qFEMesherQualityHistogramWidget.h
/// Quality at a glance: five QPainter histograms (aspect ratio, radius ratio, minimum dihedral
/// angle on a 0-90 degree axis, volume on a logarithmic axis, scaled Jacobian) for the whole mesh
/// or one material, each with its definition as tooltip, its bad threshold drawn as a red line,
/// the number of bad tets printed and, once the per-tet values are given (`setTetQuality`), a
/// button naming the worst tet that asks the view to show it (`showElementRequested`); beside them
/// the fidelity table (Dice, volume error per label, a status that flags a label missing, a poor
/// fit or a volume change above a tolerance spin box; boundary distances; missing labels) with a
/// note on Dice against volume error. Pure QWidget painting: works offscreen.

#include <femesher/Types.h>
#include <femesher/stages/Fidelity.h>
#include <femesher/stages/Quality.h>

#include <QWidget>

#include <limits>
#include <memory>
#include <optional>

class QComboBox;
class QDoubleSpinBox;
class QLabel;
class QPushButton;
class QTableWidget;

/// One histogram drawn with QPainter.
class qFEMesherHistogramPlot : public QWidget {
  Q_OBJECT
 public:
  explicit qFEMesherHistogramPlot(QWidget* parent = nullptr);
  /// `metric` may be null (empty plot with the title).
  void setMetric(const QString& title, const femesher::MetricSummary* metric);
  /// Draw the x axis over [lo, hi] instead of the histogram's edges (bins outside are dropped).
  void setDisplayRange(double lo, double hi) { displayLo_ = lo; displayHi_ = hi; update(); }
  /// Logarithmic x axis (the histogram's edges must then be positive and geometric).
  void setLogScale(bool on) { log_ = on; update(); }
  bool isLogScale() const { return log_; }
  double displayLow() const;
  double displayHigh() const;
  const femesher::Histogram& histogram() const { return metric_.histogram; }
  QString title() const { return title_; }
  bool hasData() const { return hasData_; }
  size_t totalCount() const;
  size_t badCount() const { return metric_.badCount; }
  /// The caption printed under the title, e.g. "12 bad (> 3)".
  QString badText() const;
  QSize sizeHint() const override { return {260, 170}; }
  QSize minimumSizeHint() const override { return {130, 100}; }

 protected:
  void paintEvent(QPaintEvent*) override;

 private:
  QString title_;
  femesher::MetricSummary metric_;
  bool hasData_ = false;
  bool log_ = false;
  double displayLo_ = std::numeric_limits<double>::quiet_NaN();
  double displayHi_ = std::numeric_limits<double>::quiet_NaN();
};

class qFEMesherQualityHistogramWidget : public QWidget {
  Q_OBJECT
 public:
  explicit qFEMesherQualityHistogramWidget(QWidget* parent = nullptr);

  /// Show a run's reports. `materials` names and colours the per-material choices.
  void setReports(const femesher::QualityReport& quality, const femesher::FidelityReport* fidelity,
                  const std::vector<femesher::Material>& materials);
  void clear();
  /// Per-tet values of the mesh the reports describe (same tet order): they give the volume plot
  /// its logarithmic bins and each plot its worst tet. Null clears them.
  void setTetQuality(std::shared_ptr<const femesher::TetMesh> mesh,
                     std::shared_ptr<const femesher::TetQuality> quality);
  /// The worst tet of plot i in the selected material, -1 when not known.
  long long worstElement(int i) const { return worst_[i]; }
  QPushButton* worstButton(int i) const { return worstButtons_[i]; }
  /// The definition shown as plot i's tooltip.
  static QString metricDefinition(int i);

  /// Select "All materials" (label = kExteriorLabel) or one material label.
  bool selectMaterial(int32_t label);
  int32_t selectedMaterial() const;

  // For tests and the app.
  QComboBox* materialCombo() const { return combo_; }
  /// 0 aspect ratio, 1 radius ratio, 2 min dihedral, 3 volume, 4 scaled Jacobian.
  qFEMesherHistogramPlot* plot(int i) const { return plots_[i]; }
  static constexpr int plotCount() { return 5; }
  QTableWidget* fidelityTable() const { return fidelity_; }
  /// Volume change (percent) above which a label's status says so instead of "ok" (default 5).
  QDoubleSpinBox* volumeToleranceSpin() const { return tolerance_; }
  QLabel* fidelityNote() const { return fidelityNote_; }
  QLabel* summaryLabel() const { return summary_; }

 signals:
  /// "Show worst" was pressed: the view should show this tet.
  void showElementRequested(long long tet);

 private slots:
  void updatePlots();

 private:
  femesher::QualityReport quality_;
  std::optional<femesher::FidelityReport> fidelityReport_;
  bool hasQuality_ = false;
  QComboBox* combo_ = nullptr;
  qFEMesherHistogramPlot* plots_[5] = {};
  QPushButton* worstButtons_[5] = {};
  long long worst_[5] = {-1, -1, -1, -1, -1};
  femesher::MetricSummary logVolume_;
  std::shared_ptr<const femesher::TetMesh> tetMesh_;
  std::shared_ptr<const femesher::TetQuality> tetQuality_;
  QTableWidget* fidelity_ = nullptr;
  QLabel* summary_ = nullptr;
  QLabel* distances_ = nullptr;
  QLabel* fidelityNote_ = nullptr;
  QDoubleSpinBox* tolerance_ = nullptr;
  std::vector<femesher::Material> materials_;
  void fillFidelityTable();
};
