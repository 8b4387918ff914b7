// SPDX-License-Identifier: GPL-3.0-or-later

// Qt includes
#include <QDebug>
#include <QVBoxLayout>

// Slicer includes
#include "qSlicerFEMesherModuleWidget.h"
#include "ui_qSlicerFEMesherModuleWidget.h"

// FEMesher includes
#include "vtkSlicerFEMesherLogic.h"
#include <qFEMesherPanelWidget.h>

// MRML includes
#include <vtkMRMLModelNode.h>
#include <vtkMRMLScene.h>

//-----------------------------------------------------------------------------
class qSlicerFEMesherModuleWidgetPrivate: public Ui_qSlicerFEMesherModuleWidget
{
public:
  qSlicerFEMesherModuleWidgetPrivate();
  vtkSlicerFEMesherLogic* logic() const;

  qFEMesherPanelWidget* Panel = nullptr;
  qSlicerFEMesherModuleWidget* q_ptr = nullptr;
};

//-----------------------------------------------------------------------------
// qSlicerFEMesherModuleWidgetPrivate methods

//-----------------------------------------------------------------------------
qSlicerFEMesherModuleWidgetPrivate::qSlicerFEMesherModuleWidgetPrivate() = default;

//-----------------------------------------------------------------------------
vtkSlicerFEMesherLogic* qSlicerFEMesherModuleWidgetPrivate::logic() const
{
  return vtkSlicerFEMesherLogic::SafeDownCast(this->q_ptr->logic());
}

//-----------------------------------------------------------------------------
// qSlicerFEMesherModuleWidget methods

//-----------------------------------------------------------------------------
qSlicerFEMesherModuleWidget::qSlicerFEMesherModuleWidget(QWidget* _parent)
  : Superclass( _parent )
  , d_ptr( new qSlicerFEMesherModuleWidgetPrivate )
{
  d_ptr->q_ptr = this;
}

//-----------------------------------------------------------------------------
qSlicerFEMesherModuleWidget::~qSlicerFEMesherModuleWidget() = default;

//-----------------------------------------------------------------------------
void qSlicerFEMesherModuleWidget::setup()
{
  Q_D(qSlicerFEMesherModuleWidget);
  d->setupUi(this);
  this->Superclass::setup();

  // The same panel as the standalone app; input comes from the node selector instead of a file.
  d->Panel = new qFEMesherPanelWidget(d->PanelPlaceholder);
  auto* layout = new QVBoxLayout(d->PanelPlaceholder);
  layout->setContentsMargins(0, 0, 0, 0);
  layout->addWidget(d->Panel);
  d->Panel->setFileInputVisible(false);

  connect(d->InputNodeComboBox, SIGNAL(currentNodeChanged(vtkMRMLNode*)),
          this, SLOT(onInputNodeChanged(vtkMRMLNode*)));
  // Results arrive on the main thread (queued from the worker), where MRML may be modified.
  connect(d->Panel, &qFEMesherPanelWidget::runSucceeded,
          this, &qSlicerFEMesherModuleWidget::onRunSucceeded);
}

//-----------------------------------------------------------------------------
void qSlicerFEMesherModuleWidget::onInputNodeChanged(vtkMRMLNode* node)
{
  Q_D(qSlicerFEMesherModuleWidget);
  vtkSlicerFEMesherLogic* logic = d->logic();
  if (!node || !logic)
  {
    d->Panel->setVolume(nullptr, QString());
    return;
  }
  auto volume = std::make_shared<femesher::LabelVolume>();
  const std::string error = logic->LabelVolumeFromNode(node, *volume);
  if (!error.empty())
  {
    qWarning() << Q_FUNC_INFO << ": " << error.c_str();
    d->Panel->setVolume(nullptr, QString());
    return;
  }
  d->Panel->setVolume(volume, QString::fromUtf8(node->GetName()));
}

//-----------------------------------------------------------------------------
void qSlicerFEMesherModuleWidget::onRunSucceeded(
  std::shared_ptr<const femesher::PipelineResult> result)
{
  Q_D(qSlicerFEMesherModuleWidget);
  vtkSlicerFEMesherLogic* logic = d->logic();
  if (!result || !logic || !this->mrmlScene())
  {
    return;
  }
  vtkMRMLModelNode* model = vtkMRMLModelNode::SafeDownCast(d->OutputModelComboBox->currentNode());
  model = logic->UpdateModelNodeFromMesh(result->mesh, model);
  if (model)
  {
    d->OutputModelComboBox->setCurrentNode(model);
  }
}
