// SPDX-License-Identifier: GPL-3.0-or-later
#include "qFEMesherQualityHistogramWidget.h"

#include <QComboBox>
#include <QDoubleSpinBox>
#include <QGridLayout>
#include <QHBoxLayout>
#include <QHeaderView>
#include <QLabel>
#include <QPainter>
#include <QPainterPath>
#include <QPixmap>
#include <QPushButton>
#include <QTableWidget>
#include <QVBoxLayout>

#include <algorithm>
#include <cmath>

namespace {

constexpr int kPlots = 5;
const char* kMetricNames[kPlots] = {"aspect_ratio", "radius_ratio", "min_dihedral", "volume",
                                    "scaled_jacobian"};
const char* kMetricTitles[kPlots] = {"Aspect ratio", "Radius ratio", "Min dihedral (\u00b0)",
                                     "Volume (mm\u00b3, log)", "Scaled Jacobian"};
/// Which end is worse: +1 the largest value, -1 the smallest.
const int kWorseSide[kPlots] = {+1, +1, -1, -1, -1};

const std::vector<double>* valuesOf(const femesher::TetQuality& q, int i) {
  switch (i) {
    case 0: return &q.aspectRatio;
    case 1: return &q.radiusRatio;
    case 2: return &q.minDihedral;
    case 3: return &q.volume;
    default: return &q.scaledJacobian;
  }
}

QString number(double v) {
  if (!std::isfinite(v)) return QStringLiteral("inf");
  const double a = std::abs(v);
  if (a != 0 && (a < 1e-3 || a >= 1e5)) return QString::number(v, 'e', 1);
  if (a >= 100) return QString::number(v, 'f', 0);
  if (a >= 10) return QString::number(v, 'f', 1);
  return QString::number(v, 'f', 2);
}

size_t maxCountOf(const femesher::Histogram& h) {
  size_t m = 1;
  for (size_t c : h.counts) m = std::max(m, c);
  return m;
}

QIcon swatch(const std::array<double, 3>& c) {
  QPixmap pm(12, 12);
  pm.fill(QColor::fromRgbF(c[0], c[1], c[2]));
  return QIcon(pm);
}

}  // namespace

// --- qFEMesherHistogramPlot ----------------------------------------------------------------------

qFEMesherHistogramPlot::qFEMesherHistogramPlot(QWidget* parent) : QWidget(parent) {
  setSizePolicy(QSizePolicy::Expanding, QSizePolicy::Expanding);
  setAttribute(Qt::WA_OpaquePaintEvent, false);
}

double qFEMesherHistogramPlot::displayLow() const {
  if (std::isfinite(displayLo_)) return displayLo_;
  return metric_.histogram.edges.empty() ? 0.0 : metric_.histogram.edges.front();
}

double qFEMesherHistogramPlot::displayHigh() const {
  if (std::isfinite(displayHi_)) return displayHi_;
  return metric_.histogram.edges.empty() ? 1.0 : metric_.histogram.edges.back();
}

void qFEMesherHistogramPlot::setMetric(const QString& title, const femesher::MetricSummary* m) {
  title_ = title;
  hasData_ = m != nullptr && !m->histogram.counts.empty();
  metric_ = m ? *m : femesher::MetricSummary{};
  update();
}

size_t qFEMesherHistogramPlot::totalCount() const {
  size_t n = 0;
  for (size_t c : metric_.histogram.counts) n += c;
  return n;
}

QString qFEMesherHistogramPlot::badText() const {
  if (!hasData_) return tr("no data");
  const QString op = metric_.badAbove ? (metric_.badInclusive ? ">=" : ">")
                                      : (metric_.badInclusive ? "<=" : "<");
  if (metric_.name == "volume") return tr("%1 tets, range %2 .. %3").arg(totalCount()).arg(
                                           number(metric_.min), number(metric_.max));
  return tr("%1 bad (%2 %3), %4%").arg(metric_.badCount).arg(op, number(metric_.badThreshold))
      .arg(100.0 * metric_.badShare, 0, 'f', 2);
}

void qFEMesherHistogramPlot::paintEvent(QPaintEvent*) {
  QPainter p(this);
  p.setRenderHint(QPainter::Antialiasing, true);
  const QRect r = rect();
  p.fillRect(r, palette().base());
  p.setPen(palette().mid().color());
  p.drawRect(r.adjusted(0, 0, -1, -1));
  const QFontMetrics fm(font());
  const int lineH = fm.height();
  p.setPen(palette().text().color());
  QFont bold = font();
  bold.setBold(true);
  p.setFont(bold);
  // A title or count line wider than the plot ends in "..." rather than being cut off mid-letter.
  p.drawText(QRect(6, 3, r.width() - 12, lineH), Qt::AlignLeft | Qt::AlignVCenter,
             QFontMetrics(bold).elidedText(title_, Qt::ElideRight, r.width() - 12));
  p.setFont(font());
  const bool hasBad = hasData_ && metric_.badCount > 0 && metric_.name != "volume";
  p.setPen(hasBad ? QColor(190, 30, 30) : palette().text().color());
  p.drawText(QRect(6, 3 + lineH, r.width() - 12, lineH), Qt::AlignLeft | Qt::AlignVCenter,
             fm.elidedText(badText(), Qt::ElideRight, r.width() - 12));
  if (!hasData_) return;

  const auto& h = metric_.histogram;
  const int left = fm.horizontalAdvance(QString::number(maxCountOf(metric_.histogram))) + 10;
  const QRect plot(left, 6 + 2 * lineH + 4, r.width() - left - 10, r.height() - (6 + 2 * lineH + 4) - lineH - 6);
  if (plot.width() < 20 || plot.height() < 20) return;
  size_t maxCount = 1;
  for (size_t c : h.counts) maxCount = std::max(maxCount, c);
  const double lo = displayLow(), hi = displayHigh();
  const bool logX = log_ && lo > 0 && hi > lo;
  const double l0 = logX ? std::log10(lo) : lo, l1 = logX ? std::log10(hi) : hi;
  const double span = l1 > l0 ? l1 - l0 : 1.0;
  auto xOf = [&](double v) {
    const double t = ((logX ? std::log10(std::max(v, lo)) : v) - l0) / span;
    return plot.left() + std::clamp(t, 0.0, 1.0) * plot.width();
  };
  // Bars: good blue, bad red (a bin counts as bad when its centre is on the bad side).
  const QColor good(70, 130, 200), bad(215, 80, 70);
  for (size_t i = 0; i < h.counts.size(); ++i) {
    if (h.counts[i] == 0 || h.edges[i] >= hi) continue;
    const double x0 = xOf(h.edges[i]), x1 = xOf(h.edges[i + 1]);
    // Square-root scale keeps small but important tails (slivers) visible.
    const double frac = std::sqrt(double(h.counts[i]) / double(maxCount));
    const double bh = std::max(1.0, frac * plot.height());
    const double centre = 0.5 * (h.edges[i] + h.edges[i + 1]);
    const bool isBad = metric_.name != "volume" &&
                       (metric_.badAbove ? centre > metric_.badThreshold
                                         : centre < metric_.badThreshold);
    p.fillRect(QRectF(x0, plot.bottom() - bh, std::max(1.0, x1 - x0 - 1), bh), isBad ? bad : good);
  }
  // Axes.
  p.setPen(palette().text().color());
  p.drawLine(plot.bottomLeft(), plot.bottomRight());
  p.drawLine(plot.bottomLeft(), plot.topLeft());
  p.drawText(QRect(0, plot.top() - lineH / 2, plot.left() - 3, lineH),
             Qt::AlignRight | Qt::AlignVCenter, QString::number(maxCount));
  p.drawText(QRect(0, plot.bottom() - lineH / 2, plot.left() - 3, lineH),
             Qt::AlignRight | Qt::AlignVCenter, QStringLiteral("0"));
  p.drawText(QRect(plot.left() - 20, plot.bottom() + 2, 80, lineH), Qt::AlignLeft, number(lo));
  p.drawText(QRect(plot.right() - 80, plot.bottom() + 2, 80, lineH), Qt::AlignRight, number(hi));
  if (logX)  // a tick at each power of ten inside the range
    for (double d = std::pow(10.0, std::ceil(l0)); d < hi; d *= 10.0) {
      const double x = xOf(d);
      p.drawLine(QPointF(x, plot.bottom()), QPointF(x, plot.bottom() + 3));
      if (x - plot.left() > 40 && plot.right() - x > 40)
        p.drawText(QRectF(x - 30, plot.bottom() + 2, 60, lineH), Qt::AlignHCenter, number(d));
    }
  else if (lo < 90 && hi >= 90 && metric_.name == "min_dihedral") {  // the regular tet's angle
    const double x = xOf(70.53);
    p.drawLine(QPointF(x, plot.bottom()), QPointF(x, plot.bottom() + 3));
    if (plot.width() > 220)
      p.drawText(QRectF(x - 30, plot.bottom() + 2, 60, lineH), Qt::AlignHCenter, QStringLiteral("70.5"));
  }
  // Bad threshold line.
  if (metric_.name != "volume" && metric_.badThreshold >= lo && metric_.badThreshold <= hi) {
    const double x = xOf(metric_.badThreshold);
    QPen pen(QColor(200, 0, 0), 2, Qt::DashLine);
    p.setPen(pen);
    p.drawLine(QPointF(x, plot.top()), QPointF(x, plot.bottom()));
    if (metric_.badAbove)
      p.drawText(QRectF(x + 3, plot.top(), 60, lineH), Qt::AlignLeft, tr("bad \u2192"));
    else
      p.drawText(QRectF(x - 63, plot.top(), 60, lineH), Qt::AlignRight, tr("\u2190 bad"));
  }
}

// --- qFEMesherQualityHistogramWidget -------------------------------------------------------------

qFEMesherQualityHistogramWidget::qFEMesherQualityHistogramWidget(QWidget* parent)
    : QWidget(parent) {
  auto* layout = new QVBoxLayout(this);
  layout->setContentsMargins(4, 4, 4, 4);
  auto* top = new QHBoxLayout;
  top->addWidget(new QLabel(tr("Quality of:"), this));
  combo_ = new QComboBox(this);
  combo_->setToolTip(tr("Show the histograms for the whole mesh or for one material"));
  combo_->setMinimumContentsLength(18);
  top->addWidget(combo_);
  summary_ = new QLabel(tr("No mesh yet: press Run."), this);
  top->addWidget(summary_, 1);
  layout->addLayout(top);

  auto* body = new QHBoxLayout;
  auto* grid = new QGridLayout;
  for (int i = 0; i < kPlots; ++i) {
    plots_[i] = new qFEMesherHistogramPlot(this);
    plots_[i]->setMetric(tr(kMetricTitles[i]), nullptr);
    plots_[i]->setObjectName(QString::fromLatin1(kMetricNames[i]));
    plots_[i]->setToolTip(metricDefinition(i));
    worstButtons_[i] = new QPushButton(tr("Show worst"), this);
    worstButtons_[i]->setEnabled(false);
    worstButtons_[i]->setSizePolicy(QSizePolicy::Ignored, QSizePolicy::Fixed);  // text never widens
    worstButtons_[i]->setMinimumWidth(60);
    worstButtons_[i]->setToolTip(tr("Point the 3-D view at the worst tet of this metric"));
    connect(worstButtons_[i], &QPushButton::clicked, this, [this, i] {
      if (worst_[i] >= 0) emit showElementRequested(worst_[i]);
    });
    auto* cell = new QVBoxLayout;
    cell->setSpacing(1);
    cell->addWidget(plots_[i], 1);
    cell->addWidget(worstButtons_[i]);
    grid->addLayout(cell, i / 3, i % 3);
  }
  plots_[2]->setDisplayRange(0.0, 90.0);  // the regular tet's 70.5 degrees near the right end
  body->addLayout(grid, 3);
  auto* fidelityColumn = new QVBoxLayout;
  fidelityColumn->addWidget(new QLabel(tr("<b>Fidelity to the labels</b>"), this));
  body->addLayout(fidelityColumn, 2);
  layout->addLayout(body, 1);

  distances_ = new QLabel(this);
  distances_->setWordWrap(true);
  fidelity_ = new QTableWidget(0, 6, this);
  fidelity_->setHorizontalHeaderLabels(
      {tr("Label"), tr("Name"), tr("Tets"), tr("Dice"), tr("Volume error"), tr("Status")});
  fidelity_->verticalHeader()->setVisible(false);
  fidelity_->setEditTriggers(QAbstractItemView::NoEditTriggers);
  fidelity_->horizontalHeader()->setStretchLastSection(true);
  fidelity_->setToolTip(
      tr("Agreement of the mesh with the input labels. Dice = 2 x the volume the material's tets "
         "share with its voxels / (tets' volume + voxels' volume): 1 = the same volume in the same "
         "place. Volume error = (mesh - voxels) / voxels: the amount, not the place."));
  fidelity_->horizontalHeaderItem(3)->setToolTip(
      tr("Volume Dice (the voxel-centre agreement, which only counts voxel centres, is in the run "
         "report as voxel_centre_dice)"));
  const QString headerTips[6] = {
      tr("Label id in the label map"), tr("Material name"), tr("Tets of this material in the mesh"),
      tr("Dice = 2 |mesh \u2229 voxels| / (|mesh| + |voxels|), by volume: 1 = the same volume in the "
         "same place. It measures place and amount together; for a thin or small label a shift of "
         "half a voxel lowers it a lot."),
      tr("Volume error = (mesh volume \u2212 voxel volume) / voxel volume: the amount only, not the "
         "place. A label can keep a good Dice and still gain or lose volume (small labels most)."),
      tr("MISSING: the label has no tets; poor fit: Dice below 0.8; volume: the volume changed by "
         "more than the tolerance below; else ok")};
  for (int c = 0; c < 6; ++c) fidelity_->horizontalHeaderItem(c)->setToolTip(headerTips[c]);
  fidelityColumn->addWidget(fidelity_, 1);
  auto* tolRow = new QHBoxLayout;
  tolRow->addWidget(new QLabel(tr("Flag volume change >"), this));
  tolerance_ = new QDoubleSpinBox(this);
  tolerance_->setRange(0.01, 100.0);
  tolerance_->setDecimals(2);
  tolerance_->setValue(5.0);
  tolerance_->setSuffix(QStringLiteral(" %"));
  tolerance_->setToolTip(tr("A label whose mesh volume differs from its voxel volume by more than "
                            "this is flagged in the Status column (small labels are the usual "
                            "cases)"));
  tolRow->addWidget(tolerance_);
  tolRow->addStretch(1);
  fidelityColumn->addLayout(tolRow);
  fidelityNote_ = new QLabel(
      tr("Dice: place and amount (1 = identical); volume error: amount only."), this);
  fidelityNote_->setWordWrap(true);
  fidelityNote_->setToolTip(headerTips[3] + QStringLiteral("<br>") + headerTips[4]);
  fidelityColumn->addWidget(fidelityNote_);
  fidelityColumn->addWidget(distances_);
  connect(tolerance_, QOverload<double>::of(&QDoubleSpinBox::valueChanged), this,
          [this] { fillFidelityTable(); });
  connect(combo_, QOverload<int>::of(&QComboBox::currentIndexChanged), this,
          &qFEMesherQualityHistogramWidget::updatePlots);
}

QString qFEMesherQualityHistogramWidget::metricDefinition(int i) {
  switch (i) {
    case 0:
      return tr("<b>Aspect ratio</b> = longest edge / (2\u221a6 \u00d7 inradius). 1 for the regular "
                "tetrahedron; it grows as a tet gets long or flat. Bad above the threshold (3).");
    case 1:
      return tr("<b>Radius ratio</b> = circumradius / (3 \u00d7 inradius). 1 for the regular "
                "tetrahedron; large for slivers and needles. Bad above the threshold (3).");
    case 2:
      return tr("<b>Minimum dihedral angle</b>: the smallest angle between two faces of a tet, in "
                "degrees. 70.5\u00b0 for the regular tetrahedron; near 0\u00b0 for slivers, which "
                "spoil finite-element stiffness matrices. Bad below the threshold (10\u00b0).");
    case 3:
      return tr("<b>Volume</b> of each tet in mm\u00b3, on a logarithmic axis (a graded mesh spans "
                "decades). No bad threshold; a volume \u2264 0 would be an inverted tet.");
    default:
      return tr("<b>Scaled Jacobian</b>: the Jacobian determinant at the worst corner divided by the "
                "product of its three edge lengths, scaled so the regular tetrahedron has 1; 0 for a "
                "flat tet, negative for an inverted one. Bad at or below 0.");
  }
}

void qFEMesherQualityHistogramWidget::setTetQuality(std::shared_ptr<const femesher::TetMesh> mesh,
                                                    std::shared_ptr<const femesher::TetQuality> quality) {
  const bool ok = mesh && quality && quality->volume.size() == mesh->tets.size() &&
                  mesh->tetLabels.size() == mesh->tets.size();
  tetMesh_ = ok ? std::move(mesh) : nullptr;
  tetQuality_ = ok ? std::move(quality) : nullptr;
  updatePlots();
}

void qFEMesherQualityHistogramWidget::clear() {
  hasQuality_ = false;
  tetMesh_.reset();
  tetQuality_.reset();
  fidelityReport_.reset();
  combo_->blockSignals(true);
  combo_->clear();
  combo_->blockSignals(false);
  fidelity_->setRowCount(0);
  distances_->clear();
  summary_->setText(tr("No mesh yet: press Run."));
  updatePlots();
}

void qFEMesherQualityHistogramWidget::setReports(const femesher::QualityReport& quality,
                                                 const femesher::FidelityReport* fidelity,
                                                 const std::vector<femesher::Material>& materials) {
  quality_ = quality;
  hasQuality_ = true;
  tetMesh_.reset();  // per-tet values of another mesh: setTetQuality() gives this one's
  tetQuality_.reset();
  if (fidelity) fidelityReport_ = *fidelity;
  else fidelityReport_.reset();

  combo_->blockSignals(true);
  combo_->clear();
  combo_->addItem(tr("All materials"), QVariant(int(femesher::kExteriorLabel)));
  for (const auto& s : quality_.perMaterial) {
    const femesher::Material* m = femesher::findMaterial(materials, s.label);
    const QString name = m ? QString::fromStdString(m->name) : tr("label %1").arg(s.label);
    if (m) combo_->addItem(swatch(m->color), QStringLiteral("%1  %2").arg(s.label).arg(name), s.label);
    else combo_->addItem(QStringLiteral("%1  %2").arg(s.label).arg(name), s.label);
  }
  combo_->setCurrentIndex(0);
  combo_->blockSignals(false);

  materials_ = materials;
  fillFidelityTable();
  updatePlots();
}

void qFEMesherQualityHistogramWidget::fillFidelityTable() {
  const std::vector<femesher::Material>& materials = materials_;
  fidelity_->setRowCount(0);
  distances_->clear();
  if (!hasQuality_) return;
  if (fidelityReport_) {
    const auto& f = *fidelityReport_;
    const double tolerance = tolerance_->value() / 100.0;
    fidelity_->setRowCount(int(f.materials.size()));
    int row = 0;
    for (const auto& m : f.materials) {
      const bool missing =
          std::find(f.missingLabels.begin(), f.missingLabels.end(), m.label) != f.missingLabels.end();
      auto* idItem = new QTableWidgetItem(QString::number(m.label));
      if (const femesher::Material* mm = femesher::findMaterial(materials, m.label))
        idItem->setIcon(swatch(mm->color));
      fidelity_->setItem(row, 0, idItem);
      fidelity_->setItem(row, 1, new QTableWidgetItem(QString::fromStdString(m.name)));
      fidelity_->setItem(row, 2, new QTableWidgetItem(QString::number(qulonglong(m.tets))));
      fidelity_->setItem(row, 3, new QTableWidgetItem(QString::number(m.dice, 'f', 4)));
      fidelity_->setItem(row, 4, new QTableWidgetItem(
                                     QStringLiteral("%1%").arg(100.0 * m.volumeError, 0, 'f', 2)));
      const bool volumeOff = std::abs(m.volumeError) > tolerance;
      auto* status = new QTableWidgetItem(
          missing ? tr("MISSING from mesh")
                  : m.dice < 0.8 ? tr("poor fit")
                                 : volumeOff ? tr("volume %1%2%").arg(m.volumeError > 0 ? "+" : "")
                                                   .arg(100.0 * m.volumeError, 0, 'f', 1)
                                             : tr("ok"));
      if (missing || m.dice < 0.8 || volumeOff) status->setForeground(QColor(190, 30, 30));
      fidelity_->setItem(row, 5, status);
      ++row;
    }
    fidelity_->resizeColumnsToContents();
    QString missingText = f.missingLabels.empty() ? tr("none") : QString();
    for (int32_t l : f.missingLabels)
      missingText += (missingText.isEmpty() ? "" : ", ") + QString::number(l);
    distances_->setText(
        tr("Boundary distance (voxels of %1 mm): mesh\u2192labels mean %2, p99 %3, max %4; "
           "labels\u2192mesh mean %5, p99 %6, max %7. Missing labels: %8.")
            .arg(number(f.voxelSize))
            .arg(number(f.meshToLabels.mean), number(f.meshToLabels.p99), number(f.meshToLabels.max),
                 number(f.labelsToMesh.mean), number(f.labelsToMesh.p99), number(f.labelsToMesh.max),
                 missingText));
  } else {
    distances_->setText(tr("Fidelity was not computed (compute_fidelity is off)."));
  }
}

bool qFEMesherQualityHistogramWidget::selectMaterial(int32_t label) {
  const int i = combo_->findData(QVariant(int(label)));
  if (i < 0) return false;
  combo_->setCurrentIndex(i);
  updatePlots();
  return true;
}

int32_t qFEMesherQualityHistogramWidget::selectedMaterial() const {
  return combo_->currentIndex() < 0 ? femesher::kExteriorLabel : combo_->currentData().toInt();
}

void qFEMesherQualityHistogramWidget::updatePlots() {
  const femesher::QualitySummary* s = nullptr;
  if (hasQuality_) {
    const int32_t sel = selectedMaterial();
    if (sel == femesher::kExteriorLabel) s = &quality_.all;
    else
      for (const auto& q : quality_.perMaterial)
        if (q.label == sel) s = &q;
  }
  const int32_t label = selectedMaterial();
  // Per-tet values: the worst tet of each metric and log-spaced volume bins, in the selection.
  const bool perTet = s && tetQuality_;
  for (int i = 0; i < kPlots; ++i) {
    worst_[i] = -1;
    if (!perTet) continue;
    const std::vector<double>& v = *valuesOf(*tetQuality_, i);
    for (size_t t = 0; t < v.size(); ++t) {
      if (label != femesher::kExteriorLabel && tetMesh_->tetLabels[t] != label) continue;
      if (std::isnan(v[t])) continue;
      if (worst_[i] < 0 || (kWorseSide[i] > 0 ? v[t] > v[size_t(worst_[i])] : v[t] < v[size_t(worst_[i])]))
        worst_[i] = (long long)t;
    }
  }
  const femesher::MetricSummary* volume = s ? s->find(kMetricNames[3]) : nullptr;
  bool logVolume = false;
  if (perTet && volume && volume->min > 0 && volume->max > volume->min) {
    logVolume_ = *volume;
    auto& h = logVolume_.histogram;
    const int bins = 40;
    const double l0 = std::log10(volume->min), l1 = std::log10(volume->max);
    h.edges.assign(size_t(bins) + 1, 0.0);
    for (int b = 0; b <= bins; ++b) h.edges[size_t(b)] = std::pow(10.0, l0 + (l1 - l0) * b / bins);
    h.edges.front() = volume->min;
    h.edges.back() = volume->max;
    h.counts.assign(size_t(bins), 0);
    const std::vector<double>& v = tetQuality_->volume;
    for (size_t t = 0; t < v.size(); ++t) {
      if (label != femesher::kExteriorLabel && tetMesh_->tetLabels[t] != label) continue;
      const double x = std::clamp(std::log10(std::max(v[t], volume->min)), l0, l1);
      ++h.counts[size_t(std::min(bins - 1, int((x - l0) / (l1 - l0) * bins)))];
    }
    logVolume = true;
  }
  for (int i = 0; i < kPlots; ++i) {
    const femesher::MetricSummary* m = s ? s->find(kMetricNames[i]) : nullptr;
    if (i == 3 && logVolume) m = &logVolume_;
    plots_[i]->setMetric(tr(kMetricTitles[i]), m);
    if (i == 3) plots_[i]->setLogScale(logVolume);
    plots_[i]->setToolTip(metricDefinition(i) +
                          (m && !m->formula.empty()
                               ? QStringLiteral("<br><tt>%1</tt>").arg(QString::fromStdString(m->formula).toHtmlEscaped())
                               : QString()));
    worstButtons_[i]->setEnabled(worst_[i] >= 0);
    worstButtons_[i]->setText(
        worst_[i] >= 0 ? tr("Worst: %1").arg(number((*valuesOf(*tetQuality_, i))[size_t(worst_[i])]))
                       : tr("Show worst"));
    worstButtons_[i]->setToolTip(worst_[i] >= 0 ? tr("Show tet %1 in the 3-D view").arg(worst_[i])
                                                : tr("Point the 3-D view at the worst tet of this metric"));
  }
  if (s) {
    summary_->setText(tr("%1 tets; %2 inverted; %3 with a dihedral angle below 5\u00b0 (whole mesh)")
                          .arg(qulonglong(s->tets))
                          .arg(qulonglong(quality_.invertedTets))
                          .arg(qulonglong(quality_.minDihedralBelow5)));
  }
}
