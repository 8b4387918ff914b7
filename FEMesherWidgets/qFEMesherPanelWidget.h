// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file qFEMesherPanelWidget.h
/// The clinician's panel: input file, material table, presets and parameters, Run / Cancel with a
/// progress bar naming the stage, the run's warnings, exports and parameter files.
///
/// The panel edits one `femesher::MeshingParameters` (the struct the CLI fills from `--preset`,
/// `--set` and `--parameters FILE`): widgets are generated from `parameterDescriptors()` (labels,
/// units, ranges, tooltips), so a parameter added to the logic appears here by itself. Saved
/// parameter files are `parametersToJson` output and are accepted by `femesher mesh --parameters`.
///
/// Material table: id, name (editable: a name other than the label map's is the parameter
/// `material.<label>.name`), colour, voxel count and volume (from `summarizeLabelMap`), a
/// "Mesh" checkbox and, for an unticked material, what becomes of it ("background": a cavity or
/// a cut; "merge": its voxels join the neighbouring material): both are the parameter
/// `material.<label>.exclude`, so a saved parameter file reproduces the panel's run from the CLI;
/// Young's modulus / Poisson ratio (into `MeshingParameters::materialProperties`, written to
/// INP/FEB exports).
///
/// Layout: the input, material table, parameters (Advanced folds out) and warnings scroll; Run,
/// Cancel, the progress bar, the message line and the export buttons stay visible below them.
///
/// Long work runs in `qFEMesherRunner` (worker thread); the panel never blocks. Errors are shown
/// inline (no modal dialogs) so the panel can be driven by tests and scripts.

#include <femesher/Parameters.h>
#include <femesher/Pipeline.h>
#include <femesher/RunContext.h>
#include <femesher/Types.h>

#include <QMap>
#include <QStringList>
#include <QWidget>

#include <map>
#include <memory>

class QComboBox;
class QVBoxLayout;
class QDoubleSpinBox;
class QGroupBox;
class QLabel;
class QLineEdit;
class QListWidget;
class QProgressBar;
class QScrollArea;
class QPushButton;
class QTableWidget;
class QThread;
class qFEMesherRunner;

Q_DECLARE_METATYPE(std::shared_ptr<const femesher::LabelVolume>)

class qFEMesherPanelWidget : public QWidget {
  Q_OBJECT
 public:
  /// Material table columns.
  enum Column { ColMesh = 0, ColId, ColName, ColColor, ColVoxels, ColExclude, ColE, ColNu, ColumnCount };

  explicit qFEMesherPanelWidget(QWidget* parent = nullptr);
  ~qFEMesherPanelWidget() override;

  // --- input ------------------------------------------------------------------------------------
  /// Read a label map (NRRD, NIfTI, MetaImage, .seg.nrrd). On failure the message is shown in
  /// the panel, returned by lastError(), and the previous volume stays.
  bool openFile(const QString& path);
  /// Use a volume given by the host (e.g. the Slicer adapter). `displayName` labels it.
  void setVolume(std::shared_ptr<const femesher::LabelVolume> volume, const QString& displayName);
  std::shared_ptr<const femesher::LabelVolume> volume() const { return volume_; }
  QString inputPath() const { return inputPath_; }
  /// Hide the file row (hosts with their own input selector).
  void setFileInputVisible(bool visible);
  QString lastError() const { return lastError_; }

  // --- parameters -------------------------------------------------------------------------------
  femesher::MeshingParameters parameters() const;
  void setParameters(const femesher::MeshingParameters& params);
  /// "coarse", "default", "fine" (case-insensitive); false for an unknown name.
  bool applyPreset(const QString& name);
  /// "coarse", "default", "fine" or "custom".
  QString currentPreset() const;
  bool saveParametersFile(const QString& path);
  bool loadParametersFile(const QString& path);
  /// The editor of a parameter key (QDoubleSpinBox, QCheckBox, QComboBox or QLineEdit).
  QWidget* parameterEditor(const QString& key) const { return editors_.value(key, nullptr); }
  QGroupBox* advancedGroup() const { return advanced_; }
  /// The scrolling part of the panel (everything above Run / Cancel).
  QScrollArea* scrollArea() const { return scroll_; }

  // --- materials --------------------------------------------------------------------------------
  QTableWidget* materialTable() const { return table_; }
  int materialRow(int32_t id) const;
  void setMaterialIncluded(int32_t id, bool included);
  bool isMaterialIncluded(int32_t id) const;
  /// What becomes of an unticked material (ignored while it is ticked).
  void setMaterialExclusion(int32_t id, femesher::Exclusion how);
  femesher::Exclusion materialExclusion(int32_t id) const;

  // --- run ----------------------------------------------------------------------------------------
  bool run();
  void cancel();
  bool isRunning() const;
  qFEMesherRunner* runner() const { return runner_; }
  /// The last successful run's result. A new run replaces it only when it succeeds: while it
  /// runs, and after it is canceled or fails, the previous result stays (and stays exportable).
  std::shared_ptr<const femesher::PipelineResult> result() const { return result_; }
  QProgressBar* progressBar() const { return progress_; }
  QListWidget* warningsList() const { return warnings_; }
  QPushButton* runButton() const { return runButton_; }
  QPushButton* cancelButton() const { return cancelButton_; }
  /// "idle", "running", "succeeded", "failed", "canceled".
  QString runState() const { return state_; }
  /// Plain-words name of a pipeline stage ("ParticleSystem" -> "Particles settling"), from the
  /// logic's stage table.
  static QString stageTitle(const QString& stage);

  // --- export -------------------------------------------------------------------------------------
  /// Write the last result (format from the extension) with the panel's material properties and
  /// element order. A result made at order 1 exported at order 2 gets its mid-edge nodes curved
  /// from what the run kept (PipelineResult::deferredCurving), the nodes a run at order 2 writes;
  /// without that the export is refused with a message (never straight-sided nodes silently).
  bool exportMesh(const QString& path);
  QStringList exportExtensions() const;
  QPushButton* exportButton(const QString& extension) const { return exportButtons_.value(extension); }

 signals:
  void volumeLoaded(std::shared_ptr<const femesher::LabelVolume> volume);
  void runStarted();
  void previewAvailable(std::shared_ptr<const femesher::PreviewSnapshot> snapshot);
  void runSucceeded(std::shared_ptr<const femesher::PipelineResult> result);
  /// After every run: state = "succeeded", "failed" or "canceled" (then result() is still the
  /// previous run's, if any).
  void runEnded(const QString& state, const QString& message);
  void progressChanged(const QString& stage, double totalFraction);
  void statusMessage(const QString& message);
  void meshExported(const QString& path);

 private slots:
  void browse();
  void onPresetChosen(int index);
  void onParameterEdited();
  void onProgress(const QString& stage, double stageFraction, double total);
  void onLog(int level, const QString& message);
  void onSucceeded(std::shared_ptr<const femesher::PipelineResult> result);
  void onFailed(int code, const QString& message);
  void onCanceled();
  void exportClicked();
  void saveParametersClicked();
  void loadParametersClicked();

 private:
  // Construction, one section of the panel each (top to bottom).
  void buildInputSection(QVBoxLayout* layout);
  void buildMaterialSection(QVBoxLayout* layout);
  void buildParameterSection(QVBoxLayout* layout);
  void buildRunSection(QVBoxLayout* layout);
  void buildWarningsSection(QVBoxLayout* layout);
  void buildExportSection(QVBoxLayout* layout);
  QWidget* makeParameterEditor(const femesher::ParameterDescriptor& d, QWidget* owner);
  void fillMaterialTable();
  void updateSizeHint();
  void updateButtons();
  void showError(const QString& message);
  void showInfo(const QString& message);
  void setEditorValue(const std::string& key, const std::string& value);
  std::string editorValue(const std::string& key) const;
  QString matchingPreset() const;
  QString keptResultNote() const;
  /// What the exports of the kept result write at the element order now set (after a switch).
  QString elementOrderNote() const;
  /// After a switch to element order 2: curves the kept result's mid-edge nodes in a worker.
  void startCurving();

  std::shared_ptr<const femesher::LabelVolume> volume_;
  std::shared_ptr<const femesher::PipelineResult> result_;
  QString inputPath_;
  QString lastError_;
  QString state_ = QStringLiteral("idle");
  qFEMesherRunner* runner_ = nullptr;
  bool updating_ = false;

  QScrollArea* scroll_ = nullptr;
  QWidget* fileRow_ = nullptr;
  QLineEdit* fileEdit_ = nullptr;
  QLabel* volumeInfo_ = nullptr;
  QTableWidget* table_ = nullptr;
  QComboBox* preset_ = nullptr;
  QLabel* sizeHint_ = nullptr;
  QGroupBox* advanced_ = nullptr;
  QMap<QString, QWidget*> editors_;
  QPushButton* runButton_ = nullptr;
  QPushButton* cancelButton_ = nullptr;
  QProgressBar* progress_ = nullptr;
  QLabel* message_ = nullptr;
  QListWidget* warnings_ = nullptr;
  QMap<QString, QPushButton*> exportButtons_;
  QPushButton* saveParams_ = nullptr;
  QPushButton* loadParams_ = nullptr;
  QThread* curving_ = nullptr;  ///< startCurving's worker while it runs
  std::shared_ptr<femesher::RunContext> curvingCtx_;
  femesher::MeshingParameters hidden_;  ///< fields without an editor keep their values here
};
