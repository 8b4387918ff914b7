// SPDX-License-Identifier: GPL-3.0-or-later
#include "qFEMesherQualityHistogramWidget.h"

#include <QComboBox>
#include <QGridLayout>
#include <QHBoxLayout>
#include <QHeaderView>
#include <QLabel>
#include <QPainter>
#include <QPainterPath>
#include <QPixmap>
#include <QTableWidget>
#include <QVBoxLayout>

#include <algorithm>
#include <cmath>

namespace {

const char* kMetricNames[4] = {"aspect_ratio", "radius_ratio", "min_dihedral", "volume"};
const char* kMetricTitles[4] = {"Aspect ratio", "Radius ratio", "Min dihedral angle (deg)",
                                "Volume (mm\u00b3)"};

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

void qFEMesherHistogramPlot::setMetric(const QString& title, const femesher::MetricSummary* m) {
  title_ = title;
  hasData_ = m != nullptr && !m->histogram.counts.empty();
  metric_ = m ? *m : femesher::MetricSummary{};
  setToolTip(m ? QString::fromStdString(m->formula) : QString());
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
  p.drawText(QRect(6, 3, r.width() - 12, lineH), Qt::AlignLeft | Qt::AlignVCenter, title_);
  p.setFont(font());
  const bool hasBad = hasData_ && metric_.badCount > 0 && metric_.name != "volume";
  p.setPen(hasBad ? QColor(190, 30, 30) : palette().text().color());
  p.drawText(QRect(6, 3 + lineH, r.width() - 12, lineH), Qt::AlignLeft | Qt::AlignVCenter,
             badText());
  if (!hasData_) return;

  const auto& h = metric_.histogram;
  const int left = fm.horizontalAdvance(QString::number(maxCountOf(metric_.histogram))) + 10;
  const QRect plot(left, 6 + 2 * lineH + 4, r.width() - left - 10, r.height() - (6 + 2 * lineH + 4) - lineH - 6);
  if (plot.width() < 20 || plot.height() < 20) return;
  size_t maxCount = 1;
  for (size_t c : h.counts) maxCount = std::max(maxCount, c);
  const double lo = h.edges.front(), hi = h.edges.back();
  const double span = hi > lo ? hi - lo : 1.0;
  auto xOf = [&](double v) { return plot.left() + (v - lo) / span * plot.width(); };
  // Bars: good blue, bad red (a bin counts as bad when its centre is on the bad side).
  const QColor good(70, 130, 200), bad(215, 80, 70);
  for (size_t i = 0; i < h.counts.size(); ++i) {
    if (h.counts[i] == 0) continue;
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
  for (int i = 0; i < 4; ++i) {
    plots_[i] = new qFEMesherHistogramPlot(this);
    plots_[i]->setMetric(tr(kMetricTitles[i]), nullptr);
    plots_[i]->setObjectName(QString::fromLatin1(kMetricNames[i]));
    grid->addWidget(plots_[i], i / 2, i % 2);
  }
  body->addLayout(grid, 3);
  auto* fidelityColumn = new QVBoxLayout;
  auto* fidelityTitle = new QLabel(tr("<b>Fidelity to the labels</b>"), this);
  fidelityColumn->addWidget(fidelityTitle);
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
  fidelityColumn->addWidget(fidelity_, 1);
  fidelityColumn->addWidget(distances_);
  connect(combo_, QOverload<int>::of(&QComboBox::currentIndexChanged), this,
          &qFEMesherQualityHistogramWidget::updatePlots);
}

void qFEMesherQualityHistogramWidget::clear() {
  hasQuality_ = false;
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

  // Fidelity table.
  fidelity_->setRowCount(0);
  distances_->clear();
  if (fidelityReport_) {
    const auto& f = *fidelityReport_;
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
      auto* status = new QTableWidgetItem(missing ? tr("MISSING from mesh")
                                                  : (m.dice < 0.8 ? tr("poor fit") : tr("ok")));
      if (missing || m.dice < 0.8) status->setForeground(QColor(190, 30, 30));
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
  updatePlots();
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
    const int32_t label = selectedMaterial();
    if (label == femesher::kExteriorLabel) s = &quality_.all;
    else
      for (const auto& q : quality_.perMaterial)
        if (q.label == label) s = &q;
  }
  for (int i = 0; i < 4; ++i)
    plots_[i]->setMetric(tr(kMetricTitles[i]), s ? s->find(kMetricNames[i]) : nullptr);
  if (s) {
    summary_->setText(tr("%1 tets; %2 inverted; %3 with a dihedral angle below 5\u00b0 (whole mesh)")
                          .arg(qulonglong(s->tets))
                          .arg(qulonglong(quality_.invertedTets))
                          .arg(qulonglong(quality_.minDihedralBelow5)));
  }
}
