// SPDX-License-Identifier: GPL-3.0-or-later
#ifndef __qSlicerFEMesherModuleWidget_h
#define __qSlicerFEMesherModuleWidget_h

// Slicer includes
#include "qSlicerAbstractModuleWidget.h"

#include "qSlicerFEMesherModuleExport.h"

#include <femesher/Pipeline.h>

#include <memory>

class qSlicerFEMesherModuleWidgetPrivate;
class vtkMRMLNode;

/// The module panel: a node selector for the input (segmentation or label map) and the output
/// model, and the same qFEMesherPanelWidget as the standalone app (its file row hidden).
class Q_SLICER_QTMODULES_FEMESHER_EXPORT qSlicerFEMesherModuleWidget :
  public qSlicerAbstractModuleWidget
{
  Q_OBJECT

public:
  typedef qSlicerAbstractModuleWidget Superclass;
  qSlicerFEMesherModuleWidget(QWidget* parent = nullptr);
  ~qSlicerFEMesherModuleWidget() override;

public slots:
  void onInputNodeChanged(vtkMRMLNode* node);
  void onRunSucceeded(std::shared_ptr<const femesher::PipelineResult> result);

protected:
  QScopedPointer<qSlicerFEMesherModuleWidgetPrivate> d_ptr;

  void setup() override;

private:
  Q_DECLARE_PRIVATE(qSlicerFEMesherModuleWidget);
  Q_DISABLE_COPY(qSlicerFEMesherModuleWidget);
};

#endif
