// SPDX-License-Identifier: GPL-3.0-or-later
#include "qFEMesherPanelWidget.h"

#include "qFEMesherRunner.h"

#include <femesher/StageTable.h>
#include <femesher/io/AtomicFile.h>
#include <femesher/io/LabelMapIO.h>
#include <femesher/io/MeshIO.h>

#include <QCheckBox>
#include <QComboBox>
#include <QDoubleSpinBox>
#include <QDoubleValidator>
#include <QFileDialog>
#include <QFileInfo>
#include <QFont>
#include <QFormLayout>
#include <QGridLayout>
#include <QGroupBox>
#include <QHBoxLayout>
#include <QHeaderView>
#include <QLabel>
#include <QLineEdit>
#include <QListWidget>
#include <QPixmap>
#include <QProgressBar>
#include <QPushButton>
#include <QScrollArea>
#include <QTableWidget>
#include <QThread>
#include <QVBoxLayout>

#include <cmath>
#include <fstream>
#include <set>

namespace {

/// The parameters shown in plain words at the top; all others go to "Advanced".
const char* const kKeyParameters[] = {"target_edge_length", "edge_length_factor",
                                      "smoothing_sigma", "min_voxels"};

bool isKeyParameter(const std::string& key) {
  for (const char* k : kKeyParameters)
    if (key == k) return true;
  return false;
}

QString unitSuffix(const std::string& unit) {
  if (unit.empty()) return {};
  if (unit == "mm^3") return QStringLiteral(" mm\u00b3");
  if (unit == "degrees") return QStringLiteral("\u00b0");
  return QStringLiteral(" ") + QString::fromStdString(unit);
}

QString describe(const femesher::ParameterDescriptor& d) {
  QString tip = QStringLiteral("<b>%1</b> (<tt>%2</tt>)<br>%3")
                    .arg(QString::fromStdString(d.label), QString::fromStdString(d.key),
                         QString::fromStdString(d.help).toHtmlEscaped());
  if (d.type == "double" || d.type == "int")
    tip += QStringLiteral("<br>Range %1 .. %2 %3, default %4")
               .arg(d.minimum).arg(d.maximum).arg(QString::fromStdString(d.unit),
                                                  QString::fromStdString(d.defaultValue));
  return tip;
}

QString extensionTitle(const std::string& ext) {
  if (ext == ".vtu") return QObject::tr("VTU (ParaView, Slicer)");
  if (ext == ".inp") return QObject::tr("INP (Abaqus, CalculiX)");
  if (ext == ".msh") return QObject::tr("MSH (Gmsh)");
  if (ext == ".mesh") return QObject::tr("MESH (Medit)");
  if (ext == ".feb") return QObject::tr("FEB (FEBio)");
  if (ext == ".stl") return QObject::tr("STL (surfaces)");
  return QString::fromStdString(ext).mid(1).toUpper();
}

QPixmap colorSwatch(const std::array<double, 3>& c) {
  QPixmap pm(28, 14);
  pm.fill(QColor::fromRgbF(c[0], c[1], c[2]));
  return pm;
}

}  // namespace

qFEMesherPanelWidget::qFEMesherPanelWidget(QWidget* parent) : QWidget(parent) {
  qRegisterMetaType<std::shared_ptr<const femesher::LabelVolume>>();
  runner_ = new qFEMesherRunner(this);
  // Input, materials, parameters and warnings scroll; Run, Cancel, the progress bar, the message
  // and the exports stay at the bottom, visible however tall the Advanced section grows.
  auto* outer = new QVBoxLayout(this);
  outer->setContentsMargins(0, 0, 0, 0);
  outer->setSpacing(2);
  scroll_ = new QScrollArea(this);
  scroll_->setWidgetResizable(true);
  scroll_->setFrameShape(QFrame::NoFrame);
  scroll_->setHorizontalScrollBarPolicy(Qt::ScrollBarAlwaysOff);
  auto* content = new QWidget(scroll_);
  auto* layout = new QVBoxLayout(content);
  layout->setContentsMargins(6, 6, 6, 6);
  buildInputSection(layout);
  buildMaterialSection(layout);
  buildParameterSection(layout);
  buildWarningsSection(layout);
  layout->addStretch(1);
  scroll_->setWidget(content);
  outer->addWidget(scroll_, 1);
  auto* bottom = new QVBoxLayout;
  bottom->setContentsMargins(6, 0, 6, 6);
  buildRunSection(bottom);
  buildExportSection(bottom);
  outer->addLayout(bottom);
  connect(runner_, &qFEMesherRunner::progressChanged, this, &qFEMesherPanelWidget::onProgress);
  connect(runner_, &qFEMesherRunner::logMessage, this, &qFEMesherPanelWidget::onLog);
  connect(runner_, &qFEMesherRunner::previewAvailable, this,
          &qFEMesherPanelWidget::previewAvailable);
  connect(runner_, &qFEMesherRunner::succeeded, this, &qFEMesherPanelWidget::onSucceeded);
  connect(runner_, &qFEMesherRunner::failed, this, &qFEMesherPanelWidget::onFailed);
  connect(runner_, &qFEMesherRunner::canceled, this, &qFEMesherPanelWidget::onCanceled);

  setParameters(femesher::MeshingParameters{});
  updateButtons();
}

void qFEMesherPanelWidget::buildInputSection(QVBoxLayout* layout) {
  // --- input --------------------------------------------------------------------------------------
  fileRow_ = new QWidget(this);
  auto* fileLayout = new QHBoxLayout(fileRow_);
  fileLayout->setContentsMargins(0, 0, 0, 0);
  fileLayout->addWidget(new QLabel(tr("Segmentation:"), fileRow_));
  fileEdit_ = new QLineEdit(fileRow_);
  fileEdit_->setPlaceholderText(tr("label map: .nrrd .nii.gz .mha .seg.nrrd ..."));
  fileEdit_->setToolTip(tr("A labelled volume: every voxel holds the integer id of its material"));
  fileLayout->addWidget(fileEdit_, 1);
  auto* browse = new QPushButton(tr("Browse\u2026"), fileRow_);
  fileLayout->addWidget(browse);
  layout->addWidget(fileRow_);
  connect(browse, &QPushButton::clicked, this, &qFEMesherPanelWidget::browse);
  connect(fileEdit_, &QLineEdit::returnPressed, this, [this] { openFile(fileEdit_->text()); });
  volumeInfo_ = new QLabel(tr("No segmentation loaded."), this);
  volumeInfo_->setWordWrap(true);
  layout->addWidget(volumeInfo_);

}

void qFEMesherPanelWidget::buildMaterialSection(QVBoxLayout* layout) {
  // --- materials ----------------------------------------------------------------------------------
  auto* matBox = new QGroupBox(tr("Materials"), this);
  auto* matLayout = new QVBoxLayout(matBox);
  table_ = new QTableWidget(0, ColumnCount, matBox);
  table_->setHorizontalHeaderLabels({tr("Mesh"), tr("Label"), tr("Name"), tr("Colour"),
                                     tr("Voxels"), tr("If excluded"),
                                     tr("E (MPa)"), tr("\u03bd")});
  table_->verticalHeader()->setVisible(false);
  table_->setSelectionBehavior(QAbstractItemView::SelectRows);
  table_->horizontalHeader()->setSectionResizeMode(QHeaderView::Fixed);
  table_->horizontalHeader()->setSectionResizeMode(ColName, QHeaderView::Stretch);
  table_->horizontalHeader()->setMinimumSectionSize(24);
  const int widths[ColumnCount] = {40, 44, 90, 48, 64, 96, 78, 64};
  for (int c = 0; c < ColumnCount; ++c)
    if (c != ColName) table_->setColumnWidth(c, widths[c]);
  table_->setHorizontalScrollBarPolicy(Qt::ScrollBarAlwaysOff);
  table_->horizontalHeaderItem(ColName)->setToolTip(
      tr("Double-click to rename: the name goes into the mesh, every export and the report, and is "
         "saved with the parameters as material.<label>.name"));
  table_->horizontalHeaderItem(ColMesh)->setToolTip(
      tr("Unticked materials are not meshed: see 'If excluded' for what becomes of them"));
  table_->horizontalHeaderItem(ColExclude)->setToolTip(
      tr("For an unticked material: 'Background' leaves a cavity (or cuts it away); 'Merge' gives "
         "its voxels to the neighbouring material (the run's warnings say which). Saved with the "
         "parameters as material.<label>.exclude."));
  table_->horizontalHeaderItem(ColE)->setToolTip(
      tr("Young's modulus written to Abaqus/CalculiX (.inp) and FEBio (.feb) exports"));
  table_->horizontalHeaderItem(ColNu)->setToolTip(tr("Poisson ratio written to .inp and .feb exports"));
  // "If excluded" applies to unticked materials only.
  connect(table_, &QTableWidget::itemChanged, this, [this](QTableWidgetItem* item) {
    if (item->column() != ColMesh) return;
    if (QWidget* w = table_->cellWidget(item->row(), ColExclude))
      w->setEnabled(item->checkState() != Qt::Checked);
  });
  table_->setMinimumHeight(120);
  table_->setMaximumHeight(230);
  matLayout->addWidget(table_);
  layout->addWidget(matBox);

}

/// An editor for one parameter descriptor: check box, choice, text (tiny values) or spin box.
QWidget* qFEMesherPanelWidget::makeParameterEditor(const femesher::ParameterDescriptor& d,
                                                   QWidget* owner) {
  if (d.type == "bool") {
    auto* cb = new QCheckBox(owner);
    connect(cb, &QCheckBox::toggled, this, &qFEMesherPanelWidget::onParameterEdited);
    return cb;
  }
  if (d.type == "choice") {
    auto* combo = new QComboBox(owner);
    for (const auto& c : d.choices) combo->addItem(QString::fromStdString(c));
    connect(combo, QOverload<int>::of(&QComboBox::currentIndexChanged), this,
            &qFEMesherPanelWidget::onParameterEdited);
    return combo;
  }
  if (d.type == "string") {  // free text, checked when the run starts (contact_pairs)
    auto* edit = new QLineEdit(owner);
    edit->setPlaceholderText(tr("none"));
    connect(edit, &QLineEdit::editingFinished, this, &qFEMesherPanelWidget::onParameterEdited);
    return edit;
  }
  if (d.defaultValue.find('e') != std::string::npos) {
    // Tiny values (density 1e-9): plain text with a validator.
    auto* edit = new QLineEdit(owner);
    edit->setValidator(new QDoubleValidator(d.minimum, d.maximum, 15, edit));
    connect(edit, &QLineEdit::editingFinished, this, &qFEMesherPanelWidget::onParameterEdited);
    return edit;
  }
  auto* spin = new QDoubleSpinBox(owner);
  spin->setDecimals(d.type == "int" ? 0 : (d.unit == "mm" || d.unit == "voxels" ? 2 : 3));
  spin->setRange(d.minimum, std::min(d.maximum, d.type == "int" ? 1e12 : 1e9));
  spin->setSingleStep(d.type == "int" ? 1 : (d.maximum <= 20 ? 0.1 : 0.5));
  spin->setSuffix(unitSuffix(d.unit));
  spin->setKeyboardTracking(false);
  // 0 = computed from the voxel size: say so rather than "0.00 mm".
  if (d.key == "target_edge_length" || d.key == "h_min" || d.key == "h_max")
    spin->setSpecialValueText(tr("Automatic"));
  connect(spin, QOverload<double>::of(&QDoubleSpinBox::valueChanged), this,
          &qFEMesherPanelWidget::onParameterEdited);
  return spin;
}

void qFEMesherPanelWidget::buildParameterSection(QVBoxLayout* layout) {
  // --- parameters ---------------------------------------------------------------------------------
  auto* paramBox = new QGroupBox(tr("Mesh size"), this);
  auto* form = new QFormLayout(paramBox);
  preset_ = new QComboBox(paramBox);
  preset_->addItem(tr("Coarse (fast, large elements)"), QStringLiteral("coarse"));
  preset_->addItem(tr("Default"), QStringLiteral("default"));
  preset_->addItem(tr("Fine (small elements, slower)"), QStringLiteral("fine"));
  preset_->addItem(tr("Custom"), QStringLiteral("custom"));
  preset_->setCurrentIndex(1);
  preset_->setToolTip(tr("Ready-made settings; changing any value below switches to Custom"));
  form->addRow(tr("Preset:"), preset_);
  connect(preset_, QOverload<int>::of(&QComboBox::activated), this,
          &qFEMesherPanelWidget::onPresetChosen);
  layout->addWidget(paramBox);

  advanced_ = new QGroupBox(tr("Advanced"), this);
  advanced_->setCheckable(true);
  advanced_->setChecked(false);
  advanced_->setToolTip(tr("Particle system, TetGen quality bounds, threads, seed, default material"));
  auto* advLayout = new QVBoxLayout(advanced_);
  auto* advContent = new QWidget(advanced_);
  auto* advForm = new QFormLayout(advContent);
  advForm->setContentsMargins(0, 0, 0, 0);
  advLayout->addWidget(advContent);
  advContent->setVisible(false);
  connect(advanced_, &QGroupBox::toggled, advContent, &QWidget::setVisible);
  layout->addWidget(advanced_);

  // Editors from the descriptors: key parameters under the preset, the others in Advanced.
  for (const auto& d : femesher::parameterDescriptors()) {
    const QString key = QString::fromStdString(d.key);
    QWidget* owner = isKeyParameter(d.key) ? paramBox : advContent;
    QWidget* editor = makeParameterEditor(d, owner);
    editor->setObjectName(key);
    editor->setToolTip(describe(d));
    editors_.insert(key, editor);
    QString label = QString::fromStdString(d.label);
    if (d.key == "target_edge_length") label = tr("Element size");
    if (d.key == "edge_length_factor") label = tr("Automatic size (\u00d7 voxel)");
    if (d.key == "smoothing_sigma") label = tr("Surface smoothing");
    if (d.key == "min_voxels") label = tr("Drop labels smaller than");
    auto* labelWidget = new QLabel(label + QStringLiteral(":"), owner);
    labelWidget->setToolTip(describe(d));
    if (owner == paramBox) form->addRow(labelWidget, editor);
    else advForm->addRow(labelWidget, editor);
  }
  sizeHint_ = new QLabel(paramBox);
  sizeHint_->setWordWrap(true);
  form->addRow(sizeHint_);
  auto* paramButtons = new QHBoxLayout;
  saveParams_ = new QPushButton(tr("Save parameters\u2026"), paramBox);
  saveParams_->setToolTip(tr("Save as JSON; the CLI reads it with: femesher mesh IN -o OUT --parameters FILE"));
  loadParams_ = new QPushButton(tr("Load parameters\u2026"), paramBox);
  paramButtons->addWidget(saveParams_);
  paramButtons->addWidget(loadParams_);
  form->addRow(paramButtons);
  connect(saveParams_, &QPushButton::clicked, this, &qFEMesherPanelWidget::saveParametersClicked);
  connect(loadParams_, &QPushButton::clicked, this, &qFEMesherPanelWidget::loadParametersClicked);

}

void qFEMesherPanelWidget::buildRunSection(QVBoxLayout* layout) {
  // --- run ------------------------------------------------------------------------------------------
  auto* runRow = new QHBoxLayout;
  runButton_ = new QPushButton(tr("Run"), this);
  runButton_->setToolTip(tr("Mesh the ticked materials with the settings above"));
  QFont bold = runButton_->font();
  bold.setBold(true);
  runButton_->setFont(bold);
  cancelButton_ = new QPushButton(tr("Cancel"), this);
  cancelButton_->setToolTip(tr("Stop the run (within a second); nothing is written"));
  runRow->addWidget(runButton_, 2);
  runRow->addWidget(cancelButton_, 1);
  layout->addLayout(runRow);
  progress_ = new QProgressBar(this);
  progress_->setRange(0, 1000);
  progress_->setValue(0);
  progress_->setTextVisible(true);
  progress_->setFormat(tr("Idle"));
  layout->addWidget(progress_);
  message_ = new QLabel(this);
  message_->setObjectName(QStringLiteral("message"));
  message_->setWordWrap(true);
  message_->setTextInteractionFlags(Qt::TextSelectableByMouse);
  layout->addWidget(message_);
  connect(runButton_, &QPushButton::clicked, this, [this] { run(); });
  connect(cancelButton_, &QPushButton::clicked, this, &qFEMesherPanelWidget::cancel);
}

void qFEMesherPanelWidget::buildWarningsSection(QVBoxLayout* layout) {
  auto* warnBox = new QGroupBox(tr("Warnings"), this);
  auto* warnLayout = new QVBoxLayout(warnBox);
  warnings_ = new QListWidget(warnBox);
  warnings_->setWordWrap(true);
  warnings_->setMinimumHeight(50);
  warnings_->setMaximumHeight(110);
  warnLayout->addWidget(warnings_);
  layout->addWidget(warnBox);

}

void qFEMesherPanelWidget::buildExportSection(QVBoxLayout* layout) {
  // --- export ---------------------------------------------------------------------------------------
  auto* exportBox = new QGroupBox(tr("Export mesh"), this);
  auto* exportGrid = new QGridLayout(exportBox);
  int i = 0;
  for (const auto& ext : femesher::supportedMeshExtensions()) {
    auto* b = new QPushButton(extensionTitle(ext), exportBox);
    b->setProperty("extension", QString::fromStdString(ext));
    b->setObjectName(QStringLiteral("export") + QString::fromStdString(ext));
    b->setToolTip(tr("Save the mesh as %1").arg(QString::fromStdString(ext)));
    exportGrid->addWidget(b, i / 4, i % 4);
    exportButtons_.insert(QString::fromStdString(ext), b);
    connect(b, &QPushButton::clicked, this, &qFEMesherPanelWidget::exportClicked);
    ++i;
  }
  layout->addWidget(exportBox);

}

qFEMesherPanelWidget::~qFEMesherPanelWidget() {
  if (curving_) {
    disconnect(curving_, nullptr, this, nullptr);
    curvingCtx_->cancel();
    curving_->wait();
    delete curving_;
  }
}

void qFEMesherPanelWidget::startCurving() {
  if (curving_ || !result_ || result_->midEdgeNodes || !result_->deferredCurving) return;
  // Curve the kept result's mid-edge nodes in a worker (about 2 s on a 500 k-tet knee), so the
  // export after the switch finds them ready; an export that comes first waits for them
  // (DeferredCurving curves once, under a lock). The worker holds its own reference to the result.
  auto result = result_;
  auto ctx = std::make_shared<femesher::RunContext>();
  curvingCtx_ = ctx;
  curving_ = QThread::create([result, ctx] {
    // A failure (or a cancel) leaves the nodes uncomputed: the export curves them itself and
    // shows the error there.
    femesher::runGuarded([&] { result->deferredCurving->midEdgeNodes(result->mesh, *ctx); });
  });
  connect(curving_, &QThread::finished, this, [this] {
    curving_->deleteLater();
    curving_ = nullptr;
  });
  curving_->start(QThread::LowPriority);
}

// --- input ----------------------------------------------------------------------------------------

void qFEMesherPanelWidget::setFileInputVisible(bool visible) { fileRow_->setVisible(visible); }

void qFEMesherPanelWidget::browse() {
  const QString path = QFileDialog::getOpenFileName(
      this, tr("Open segmentation"), QFileInfo(inputPath_).absolutePath(),
      tr("Label maps (*.nrrd *.nhdr *.nii *.nii.gz *.mha *.mhd *.seg.nrrd);;All files (*)"));
  if (!path.isEmpty()) openFile(path);
}

bool qFEMesherPanelWidget::openFile(const QString& path) {
  if (isRunning()) {
    showError(tr("A run is going on: cancel it before opening another file."));
    return false;
  }
  auto r = femesher::readLabelMap(path.toStdString());
  if (!r) {
    showError(QString::fromStdString(r.status().message()));
    return false;
  }
  inputPath_ = path;
  fileEdit_->setText(path);
  setVolume(std::make_shared<const femesher::LabelVolume>(std::move(r).value()),
            QFileInfo(path).fileName());
  return true;
}

void qFEMesherPanelWidget::setVolume(std::shared_ptr<const femesher::LabelVolume> volume,
                                     const QString& displayName) {
  volume_ = std::move(volume);
  result_.reset();
  warnings_->clear();
  progress_->setValue(0);
  progress_->setFormat(tr("Idle"));
  state_ = QStringLiteral("idle");
  if (volume_) {
    const auto& v = *volume_;
    volumeInfo_->setText(tr("<b>%1</b>: %2 \u00d7 %3 \u00d7 %4 voxels of %5 \u00d7 %6 \u00d7 %7 mm, "
                            "%8 materials")
                             .arg(displayName.toHtmlEscaped())
                             .arg(v.dims[0]).arg(v.dims[1]).arg(v.dims[2])
                             .arg(v.spacing[0], 0, 'g', 3).arg(v.spacing[1], 0, 'g', 3)
                             .arg(v.spacing[2], 0, 'g', 3).arg(v.materials.size()));
  } else {
    volumeInfo_->setText(tr("No segmentation loaded."));
  }
  fillMaterialTable();
  updateSizeHint();
  showInfo(volume_ ? tr("Loaded %1. Choose the materials and the size, then press Run.")
                         .arg(displayName)
                   : QString());
  updateButtons();
  if (volume_) emit volumeLoaded(volume_);
}

void qFEMesherPanelWidget::fillMaterialTable() {
  const femesher::MeshingParameters p = parameters();
  table_->setRowCount(0);
  if (!volume_) return;
  const femesher::LabelMapSummary summary = femesher::summarizeLabelMap(*volume_);
  const bool noBackground = volume_->hasNoBackground();
  int row = 0;
  for (const auto& s : summary.labels) {
    if (s.id == 0 && !noBackground) continue;  // background is not meshed
    table_->insertRow(row);
    const femesher::Material* m = femesher::findMaterial(volume_->materials, s.id);
    auto* include = new QTableWidgetItem;
    include->setFlags(Qt::ItemIsUserCheckable | Qt::ItemIsEnabled | Qt::ItemIsSelectable);
    include->setCheckState(Qt::Checked);
    include->setData(Qt::UserRole, s.id);
    table_->setItem(row, ColMesh, include);
    auto* id = new QTableWidgetItem(QString::number(s.id));
    id->setFlags(Qt::ItemIsEnabled | Qt::ItemIsSelectable);
    table_->setItem(row, ColId, id);
    const QString mapName =
        QString::fromStdString(m ? m->name : (s.name.empty() ? "label " + std::to_string(s.id) : s.name));
    auto given = p.preprocess.names.find(s.id);
    auto* name = new QTableWidgetItem(given != p.preprocess.names.end()
                                          ? QString::fromStdString(given->second) : mapName);
    name->setData(Qt::UserRole, mapName);  // the label map's own name
    name->setFlags(Qt::ItemIsEnabled | Qt::ItemIsSelectable | Qt::ItemIsEditable);
    table_->setItem(row, ColName, name);
    const auto color = m ? m->color : femesher::defaultLabelColor(s.id);
    auto* colorItem = new QTableWidgetItem;
    colorItem->setData(Qt::DecorationRole, colorSwatch(color));
    colorItem->setData(Qt::UserRole, QColor::fromRgbF(color[0], color[1], color[2]));
    colorItem->setFlags(Qt::ItemIsEnabled);
    table_->setItem(row, ColColor, colorItem);
    auto* voxels = new QTableWidgetItem;
    voxels->setData(Qt::DisplayRole, qulonglong(s.voxels));
    voxels->setFlags(Qt::ItemIsEnabled | Qt::ItemIsSelectable);
    voxels->setTextAlignment(Qt::AlignRight | Qt::AlignVCenter);
    if (int64_t(s.voxels) < p.preprocess.minVoxels) {
      voxels->setForeground(QColor(190, 30, 30));
      voxels->setToolTip(tr("Fewer than the minimum voxels: this label will be dropped"));
    }
    else {
      voxels->setToolTip(tr("%1 mm\u00b3 in %2 connected piece(s)")
                             .arg(s.volumeMm3, 0, 'f', 1).arg(s.components));
    }
    table_->setItem(row, ColVoxels, voxels);
    name->setToolTip(tr("Label %1: %2 voxels, %3 mm\u00b3").arg(s.id).arg(qulonglong(s.voxels))
                         .arg(s.volumeMm3, 0, 'f', 1));
    auto* exclude = new QComboBox(table_);
    exclude->addItem(tr("Background"), int(femesher::Exclusion::Background));
    exclude->addItem(tr("Merge"), int(femesher::Exclusion::MergeIntoNeighbour));
    exclude->setFrame(false);
    exclude->setToolTip(table_->horizontalHeaderItem(ColExclude)->toolTip());
    auto ex = p.preprocess.excluded.find(s.id);
    if (ex != p.preprocess.excluded.end()) {
      include->setCheckState(Qt::Unchecked);
      exclude->setCurrentIndex(exclude->findData(int(ex->second)));
    }
    exclude->setEnabled(include->checkState() != Qt::Checked);
    table_->setCellWidget(row, ColExclude, exclude);
    auto it = p.materialProperties.find(s.id);
    auto* e = new QDoubleSpinBox(table_);
    e->setRange(0.0, 1e7);
    e->setDecimals(1);
    e->setSpecialValueText(tr("default"));
    e->setValue(it != p.materialProperties.end() ? it->second.youngsModulus : 0.0);
    e->setFrame(false);
    e->setToolTip(tr("Young's modulus in MPa; 'default' uses the default material (Advanced)"));
    table_->setCellWidget(row, ColE, e);
    auto* nu = new QDoubleSpinBox(table_);
    nu->setRange(-1.0, 0.499);
    nu->setDecimals(3);
    nu->setSingleStep(0.01);
    nu->setSpecialValueText(tr("default"));
    nu->setValue(it != p.materialProperties.end() ? it->second.poissonRatio : -1.0);
    nu->setFrame(false);
    nu->setToolTip(tr("Poisson ratio; 'default' uses the default material (Advanced)"));
    table_->setCellWidget(row, ColNu, nu);
    ++row;
  }
}

int qFEMesherPanelWidget::materialRow(int32_t id) const {
  for (int r = 0; r < table_->rowCount(); ++r)
    if (table_->item(r, ColMesh)->data(Qt::UserRole).toInt() == id) return r;
  return -1;
}

void qFEMesherPanelWidget::setMaterialIncluded(int32_t id, bool included) {
  const int r = materialRow(id);
  if (r >= 0) table_->item(r, ColMesh)->setCheckState(included ? Qt::Checked : Qt::Unchecked);
}

bool qFEMesherPanelWidget::isMaterialIncluded(int32_t id) const {
  const int r = materialRow(id);
  return r >= 0 && table_->item(r, ColMesh)->checkState() == Qt::Checked;
}

void qFEMesherPanelWidget::setMaterialExclusion(int32_t id, femesher::Exclusion how) {
  const int r = materialRow(id);
  if (r < 0) return;
  auto* combo = static_cast<QComboBox*>(table_->cellWidget(r, ColExclude));
  combo->setCurrentIndex(combo->findData(int(how)));
}

femesher::Exclusion qFEMesherPanelWidget::materialExclusion(int32_t id) const {
  const int r = materialRow(id);
  if (r < 0) return femesher::Exclusion::Background;
  return femesher::Exclusion(
      static_cast<QComboBox*>(table_->cellWidget(r, ColExclude))->currentData().toInt());
}

// --- parameters -----------------------------------------------------------------------------------

void qFEMesherPanelWidget::setEditorValue(const std::string& key, const std::string& value) {
  QWidget* w = editors_.value(QString::fromStdString(key), nullptr);
  if (!w) return;
  const QString v = QString::fromStdString(value);
  if (auto* cb = qobject_cast<QCheckBox*>(w)) cb->setChecked(v == "true" || v == "1");
  else if (auto* combo = qobject_cast<QComboBox*>(w)) combo->setCurrentText(v);
  else if (auto* spin = qobject_cast<QDoubleSpinBox*>(w)) spin->setValue(v.toDouble());
  else if (auto* edit = qobject_cast<QLineEdit*>(w)) edit->setText(v);
}

std::string qFEMesherPanelWidget::editorValue(const std::string& key) const {
  QWidget* w = editors_.value(QString::fromStdString(key), nullptr);
  if (!w) return {};
  if (auto* cb = qobject_cast<QCheckBox*>(w)) return cb->isChecked() ? "true" : "false";
  if (auto* combo = qobject_cast<QComboBox*>(w)) return combo->currentText().toStdString();
  if (auto* spin = qobject_cast<QDoubleSpinBox*>(w))
    return QString::number(spin->value(), 'g', 12).toStdString();
  if (auto* edit = qobject_cast<QLineEdit*>(w)) return edit->text().trimmed().toStdString();
  return {};
}

femesher::MeshingParameters qFEMesherPanelWidget::parameters() const {
  femesher::MeshingParameters p = hidden_;
  for (const auto& d : femesher::parameterDescriptors()) {
    const std::string v = editorValue(d.key);
    // Invalid text keeps the old value; an empty text field (contact_pairs) means none.
    if (!v.empty() || d.type == "string") femesher::setParameter(p, d.key, v);
  }
  p.materialProperties.clear();
  for (int r = 0; r < table_->rowCount(); ++r) {
    const int32_t id = table_->item(r, ColMesh)->data(Qt::UserRole).toInt();
    const double e = static_cast<QDoubleSpinBox*>(table_->cellWidget(r, ColE))->value();
    const double nu = static_cast<QDoubleSpinBox*>(table_->cellWidget(r, ColNu))->value();
    if (e <= 0 && nu <= -1) continue;
    femesher::ElasticProperties props = p.defaultMaterial;
    if (e > 0) props.youngsModulus = e;
    if (nu > -1) props.poissonRatio = nu;
    p.materialProperties[id] = props;
  }
  // Materials not in the table (e.g. from a loaded parameter file) are kept.
  for (const auto& [id, props] : hidden_.materialProperties)
    if (materialRow(id) < 0) p.materialProperties[id] = props;
  // Names: a row whose name differs from the label map's sets material.<label>.name.
  p.preprocess.names.clear();
  for (const auto& [id, name] : hidden_.preprocess.names)
    if (materialRow(id) < 0) p.preprocess.names[id] = name;
  for (int r = 0; r < table_->rowCount(); ++r) {
    const int32_t id = table_->item(r, ColMesh)->data(Qt::UserRole).toInt();
    const QTableWidgetItem* name = table_->item(r, ColName);
    const QString text = name->text().simplified();
    if (!text.isEmpty() && text != name->data(Qt::UserRole).toString())
      p.preprocess.names[id] = text.toStdString();
  }
  p.preprocess.excluded.clear();
  for (const auto& [id, how] : hidden_.preprocess.excluded)
    if (materialRow(id) < 0) p.preprocess.excluded[id] = how;
  for (int r = 0; r < table_->rowCount(); ++r) {
    const int32_t id = table_->item(r, ColMesh)->data(Qt::UserRole).toInt();
    if (table_->item(r, ColMesh)->checkState() != Qt::Checked)
      p.preprocess.excluded[id] = materialExclusion(id);
  }
  return p;
}

void qFEMesherPanelWidget::setParameters(const femesher::MeshingParameters& params) {
  updating_ = true;
  hidden_ = params;
  for (const auto& d : femesher::parameterDescriptors())
    setEditorValue(d.key, femesher::getParameter(params, d.key));
  for (int r = 0; r < table_->rowCount(); ++r) {
    const int32_t id = table_->item(r, ColMesh)->data(Qt::UserRole).toInt();
    auto it = params.materialProperties.find(id);
    static_cast<QDoubleSpinBox*>(table_->cellWidget(r, ColE))
        ->setValue(it != params.materialProperties.end() ? it->second.youngsModulus : 0.0);
    static_cast<QDoubleSpinBox*>(table_->cellWidget(r, ColNu))
        ->setValue(it != params.materialProperties.end() ? it->second.poissonRatio : -1.0);
    QTableWidgetItem* name = table_->item(r, ColName);
    auto given = params.preprocess.names.find(id);
    name->setText(given != params.preprocess.names.end() ? QString::fromStdString(given->second)
                                                         : name->data(Qt::UserRole).toString());
    auto ex = params.preprocess.excluded.find(id);
    setMaterialIncluded(id, ex == params.preprocess.excluded.end());
    if (ex != params.preprocess.excluded.end()) setMaterialExclusion(id, ex->second);
  }
  updating_ = false;
  const QString match = matchingPreset();
  preset_->setCurrentIndex(preset_->findData(match));
  updateSizeHint();
}

QString qFEMesherPanelWidget::matchingPreset() const {
  femesher::MeshingParameters mine = parameters();
  mine.materialProperties.clear();
  mine.preprocess.excluded.clear();
  mine.preprocess.names.clear();
  for (const auto& name : femesher::presetNames()) {
    auto preset = femesher::presetParameters(name);
    if (!preset) continue;
    femesher::MeshingParameters p = preset.value();
    p.defaultMaterial = mine.defaultMaterial;  // material properties are not part of a preset
    p.run.threads = mine.run.threads;          // neither is the thread count
    p.elementOrder = mine.elementOrder;        // nor the element order (an export choice)
    if (femesher::parametersToJson(p) == femesher::parametersToJson(mine))
      return QString::fromStdString(name);
  }
  return QStringLiteral("custom");
}

bool qFEMesherPanelWidget::applyPreset(const QString& name) {
  auto preset = femesher::presetParameters(name.toLower().toStdString());
  if (!preset) return false;
  femesher::MeshingParameters p = preset.value();
  const femesher::MeshingParameters current = parameters();
  p.defaultMaterial = current.defaultMaterial;
  p.materialProperties = current.materialProperties;
  p.preprocess.excluded = current.preprocess.excluded;
  p.preprocess.names = current.preprocess.names;
  p.run.threads = current.run.threads;
  p.elementOrder = current.elementOrder;
  setParameters(p);
  return true;
}

QString qFEMesherPanelWidget::currentPreset() const { return preset_->currentData().toString(); }

void qFEMesherPanelWidget::onPresetChosen(int index) {
  const QString name = preset_->itemData(index).toString();
  if (name != QLatin1String("custom")) applyPreset(name);
}

void qFEMesherPanelWidget::onParameterEdited() {
  if (updating_) return;
  const QString match = matchingPreset();
  preset_->setCurrentIndex(preset_->findData(match));
  updateSizeHint();
  // The element order applies to the kept mesh's exports at once: say what they will write.
  if (sender() == editors_.value(QStringLiteral("element_order")) && result_) {
    const QString note = elementOrderNote();
    if (!result_->midEdgeNodes && parameters().elementOrder == 2 && !result_->deferredCurving)
      showError(note);
    else
      showInfo(note);
    if (parameters().elementOrder == 2) startCurving();
  }
  // The minimum voxel count colours the table.
  if (sender() == editors_.value(QStringLiteral("min_voxels"))) {
    const auto minVoxels = parameters().preprocess.minVoxels;
    for (int r = 0; r < table_->rowCount(); ++r) {
      auto* item = table_->item(r, ColVoxels);
      const bool small = item->data(Qt::DisplayRole).toLongLong() < minVoxels;
      item->setForeground(small ? QColor(190, 30, 30) : palette().text().color());
      if (small) item->setToolTip(tr("Fewer than the minimum voxels: this label will be dropped"));
    }
  }
}

void qFEMesherPanelWidget::updateSizeHint() {
  const femesher::MeshingParameters p = parameters();
  QString text;
  if (volume_) {
    const auto& s = volume_->spacing;
    const double mean = (s[0] + s[1] + s[2]) / 3.0;
    const double h = femesher::uniformEdgeLength(*volume_, p.sizing);
    text = tr("Elements about %1 mm across (voxels are %2 mm); smoothing about %3 mm.")
               .arg(h, 0, 'f', 2).arg(mean, 0, 'f', 2).arg(p.indicators.sigma * mean, 0, 'f', 2);
  } else {
    text = tr("Element size 'Automatic' = the factor below \u00d7 the mean voxel spacing.");
  }
  sizeHint_->setText(text);
}

bool qFEMesherPanelWidget::saveParametersFile(const QString& path) {
  const std::string json = femesher::parametersToJson(parameters());
  femesher::Status s = femesher::writeAtomically(path.toStdString(), [&](const std::string& tmp) {
    std::ofstream out(tmp);
    out << json << "\n";
    out.close();
    if (!out) return femesher::Status(femesher::ErrorCode::WriteFailed, "Cannot write '" + path.toStdString() + "'");
    return femesher::Status::ok();
  });
  if (!s) {
    showError(QString::fromStdString(s.message()));
    return false;
  }
  showInfo(tr("Parameters saved to %1 (use with: femesher mesh IN -o OUT --parameters %1)").arg(path));
  return true;
}

bool qFEMesherPanelWidget::loadParametersFile(const QString& path) {
  auto r = femesher::loadParametersFile(path.toStdString());
  if (!r) {
    showError(QString::fromStdString(r.status().message()));
    return false;
  }
  setParameters(r.value());
  showInfo(tr("Parameters loaded from %1").arg(path));
  return true;
}

void qFEMesherPanelWidget::saveParametersClicked() {
  const QString path = QFileDialog::getSaveFileName(this, tr("Save parameters"),
                                                    QStringLiteral("femesher-parameters.json"),
                                                    tr("JSON (*.json)"));
  if (!path.isEmpty()) saveParametersFile(path);
}

void qFEMesherPanelWidget::loadParametersClicked() {
  const QString path = QFileDialog::getOpenFileName(this, tr("Load parameters"), QString(),
                                                    tr("JSON (*.json);;All files (*)"));
  if (!path.isEmpty()) loadParametersFile(path);
}

// --- run --------------------------------------------------------------------------------------------

QString qFEMesherPanelWidget::stageTitle(const QString& stage) {
  const femesher::StageInfo* info = femesher::findStage(stage.toStdString());
  return info ? QString::fromUtf8(info->title) : stage;
}

bool qFEMesherPanelWidget::isRunning() const { return runner_->isRunning(); }

bool qFEMesherPanelWidget::run() {
  if (isRunning()) return false;
  if (!volume_) {
    showError(tr("Open a segmentation first."));
    return false;
  }
  const femesher::MeshingParameters p = parameters();
  if (femesher::Status s = femesher::validate(p); !s) {
    showError(QString::fromStdString(s.message()));
    return false;
  }
  bool anyIncluded = false;
  for (int r = 0; r < table_->rowCount(); ++r)
    anyIncluded |= table_->item(r, ColMesh)->checkState() == Qt::Checked;
  if (!anyIncluded) {
    showError(tr("Every material is unticked: tick at least one to mesh."));
    return false;
  }
  std::shared_ptr<const femesher::LabelVolume> input = volume_;
  // The previous result stays (view, histograms, exports) until this run succeeds.
  warnings_->clear();
  progress_->setValue(0);
  progress_->setFormat(tr("Starting\u2026"));
  state_ = QStringLiteral("running");
  if (!runner_->start(input, p)) {
    state_ = QStringLiteral("idle");
    showError(tr("Could not start the run."));
    return false;
  }
  showInfo(tr("Running\u2026"));
  updateButtons();
  emit runStarted();
  return true;
}

void qFEMesherPanelWidget::cancel() {
  if (!isRunning()) return;
  runner_->cancel();
  progress_->setFormat(tr("Canceling\u2026"));
  cancelButton_->setEnabled(false);
}

void qFEMesherPanelWidget::onProgress(const QString& stage, double stageFraction, double total) {
  progress_->setValue(int(std::lround(1000 * std::clamp(total, 0.0, 1.0))));
  progress_->setFormat(tr("%1 \u2014 %p%").arg(stageTitle(stage)));
  progress_->setToolTip(tr("%1 (%2): %3% of this stage done")
                           .arg(stageTitle(stage), stage).arg(int(100 * stageFraction)));
  emit progressChanged(stage, total);
}

void qFEMesherPanelWidget::onLog(int level, const QString& message) {
  if (level == int(femesher::LogLevel::Warning)) {
    auto* item = new QListWidgetItem(message, warnings_);
    item->setForeground(QColor(170, 90, 0));
  }
  if (level != int(femesher::LogLevel::Debug)) emit statusMessage(message);
}

void qFEMesherPanelWidget::onSucceeded(std::shared_ptr<const femesher::PipelineResult> result) {
  result_ = result;
  state_ = QStringLiteral("succeeded");
  progress_->setValue(1000);
  progress_->setFormat(tr("Done \u2014 %p%"));
  // The result's warnings (some may not have come through the log).
  QStringList shown;
  for (int i = 0; i < warnings_->count(); ++i) shown << warnings_->item(i)->text();
  for (const auto& w : result->warnings) {
    const QString text = QString::fromStdString(w);
    if (!shown.contains(text)) {
      auto* item = new QListWidgetItem(text, warnings_);
      item->setForeground(QColor(170, 90, 0));
    }
  }
  // The element check's warning (tets below min_dihedral_warning) first, in bold.
  if (result->meshCheck.poor()) {
    const QString poor = QString::fromStdString(femesher::poorElementsWarning(result->meshCheck));
    const auto found = warnings_->findItems(poor, Qt::MatchExactly);
    QListWidgetItem* item = found.isEmpty() ? new QListWidgetItem(poor)
                                            : warnings_->takeItem(warnings_->row(found.front()));
    QFont font = item->font();
    font.setBold(true);
    item->setFont(font);
    item->setForeground(QColor(170, 90, 0));
    warnings_->insertItem(0, item);
  }
  size_t tets = result->mesh.tets.size();
  showInfo(tr("Done in %1 s: %2 vertices, %3 tets, %4 materials. %5 warning(s).")
               .arg(result->totalSeconds, 0, 'f', 1)
               .arg(result->mesh.points.size())
               .arg(tets)
               .arg(result->mesh.materials.size())
               .arg(warnings_->count()));
  updateButtons();
  emit runSucceeded(result);
  emit runEnded(state_, message_->text());
}

QString qFEMesherPanelWidget::elementOrderNote() const {
  if (!result_) return QString();
  const bool quadraticRun = result_->midEdgeNodes != nullptr;
  if (parameters().elementOrder != 2)
    return quadraticRun ? tr("Element order 1: the exports write 4-node tets, the corners of the "
                             "mesh shown (as a run at element order 1 would).")
                        : tr("Element order 1: the exports write 4-node tets.");
  if (quadraticRun)
    return tr("Element order 2: the exports write 10-node tets with the mid-edge nodes this run "
              "curved onto the interfaces.");
  if (result_->deferredCurving)
    return tr("Element order 2: the mesh shown was made at order 1. The exports write 10-node "
              "tets whose mid-edge nodes are curved onto the run's smooth interfaces (from what "
              "the run kept, computed now in the background), exactly as a run at element order 2 "
              "would place them; no re-run needed.");
  return tr("Element order 2: the mesh shown was made at order 1 and its run kept no smooth "
            "interfaces to curve mid-edge nodes onto, so it cannot be exported with 10-node tets "
            "as a run at order 2 would write them. Run again at element order 2, or set it back "
            "to 1.");
}

QString qFEMesherPanelWidget::keptResultNote() const {
  if (!result_) return tr("There is no earlier mesh.");
  return tr("The previous mesh (%1 tets) is kept: it is the one shown and exported.")
      .arg(result_->mesh.tets.size());
}

void qFEMesherPanelWidget::onFailed(int code, const QString& message) {
  state_ = QStringLiteral("failed");
  progress_->setFormat(tr("Failed"));
  showError(tr("The run failed (%1): %2 %3")
                .arg(QString::fromLatin1(femesher::errorCodeName(femesher::ErrorCode(code))), message,
                     keptResultNote()));
  updateButtons();
  emit runEnded(state_, message);
}

void qFEMesherPanelWidget::onCanceled() {
  state_ = QStringLiteral("canceled");
  progress_->setValue(0);
  progress_->setFormat(tr("Canceled"));
  showInfo(tr("Run canceled (it stopped %1 s after Cancel); nothing was written. %2")
               .arg(runner_->lastCancelLatency(), 0, 'f', 2)
               .arg(keptResultNote()));
  updateButtons();
  emit runEnded(state_, message_->text());
}

void qFEMesherPanelWidget::updateButtons() {
  const bool running = isRunning();
  runButton_->setEnabled(!running && volume_ != nullptr);
  cancelButton_->setEnabled(running);
  // The last good mesh can be exported even while a new run goes on (it is never modified).
  for (auto* b : exportButtons_) b->setEnabled(result_ != nullptr);
  table_->setEnabled(!running);
  preset_->setEnabled(!running);
  for (auto* e : editors_) e->setEnabled(!running);
  loadParams_->setEnabled(!running);
  fileRow_->setEnabled(!running);
}

// --- export -----------------------------------------------------------------------------------------

QStringList qFEMesherPanelWidget::exportExtensions() const {
  QStringList out;
  for (const auto& e : femesher::supportedMeshExtensions()) out << QString::fromStdString(e);
  return out;
}

bool qFEMesherPanelWidget::exportMesh(const QString& path) {
  if (!result_) {
    showError(tr("Nothing to export yet: run the meshing first."));
    return false;
  }
  femesher::ExportOptions options = femesher::exportOptionsFrom(parameters());
  options.provenance = "FEMesher panel; input " + inputPath_.toStdString();
  options.contacts = result_->contacts;
  options.nodeSets = result_->boxNodeSets;
  options.midEdgeNodes = result_->midEdgeNodes;
  if (femesher::Status s = femesher::checkExportable(path.toStdString(), options); !s) {
    showError(QString::fromStdString(s.message()));
    return false;
  }
  QString curvedNote;
  if (options.elementOrder == 2 && !options.midEdgeNodes) {
    // The mesh was made at element order 1: curve its mid-edge nodes now, from what the run kept,
    // exactly as a run at order 2 would have. Never write straight-sided nodes instead.
    if (!result_->deferredCurving) {
      showError(elementOrderNote());
      return false;
    }
    femesher::RunContext ctx;
    const femesher::Status s = femesher::runGuarded([&] {
      options.midEdgeNodes = result_->deferredCurving->midEdgeNodes(result_->mesh, ctx);
    });
    if (!s) {
      showError(tr("Could not curve the mid-edge nodes for %1: %2")
                    .arg(path, QString::fromStdString(s.message())));
      return false;
    }
    const femesher::QuadraticCurvingResult f = result_->deferredCurving->figures();
    curvedNote = tr(" (10-node tets: %1 mid-edge nodes curved onto the interfaces, %2 part of the "
                    "way, as a run at element order 2 curves them)")
                     .arg(f.curvedNodes)
                     .arg(f.partlyCurvedNodes);
  }
  const femesher::Status s = femesher::writeMesh(result_->mesh, path.toStdString(), options);
  if (!s) {
    showError(QString::fromStdString(s.message()));
    return false;
  }
  showInfo(tr("Exported %1").arg(path) + curvedNote);
  emit meshExported(path);
  return true;
}

void qFEMesherPanelWidget::exportClicked() {
  const QString ext = sender()->property("extension").toString();
  QString base = QFileInfo(inputPath_).completeBaseName();
  if (base.endsWith(QLatin1String(".seg"))) base.chop(4);
  if (base.isEmpty()) base = QStringLiteral("mesh");
  const QString dir = inputPath_.isEmpty() ? QString() : QFileInfo(inputPath_).absolutePath();
  const QString path = QFileDialog::getSaveFileName(
      this, tr("Export mesh"), QDir(dir).filePath(base + ext),
      tr("%1 (*%2)").arg(extensionTitle(ext.toStdString()), ext));
  if (!path.isEmpty()) exportMesh(path.endsWith(ext) ? path : path + ext);
}

// --- messages -----------------------------------------------------------------------------------------

void qFEMesherPanelWidget::showError(const QString& message) {
  lastError_ = message;
  message_->setStyleSheet(QStringLiteral("color: #b01e1e;"));
  message_->setText(message);
  emit statusMessage(message);
}

void qFEMesherPanelWidget::showInfo(const QString& message) {
  message_->setStyleSheet(QString());
  message_->setText(message);
  if (!message.isEmpty()) emit statusMessage(message);
}
