// SPDX-License-Identifier: GPL-3.0-or-later

// FEMesher Logic includes
#include <vtkSlicerFEMesherLogic.h>

// FEMesher includes
#include "qSlicerFEMesherModule.h"
#include "qSlicerFEMesherModuleWidget.h"

//-----------------------------------------------------------------------------
class qSlicerFEMesherModulePrivate
{
public:
  qSlicerFEMesherModulePrivate();
};

//-----------------------------------------------------------------------------
// qSlicerFEMesherModulePrivate methods

//-----------------------------------------------------------------------------
qSlicerFEMesherModulePrivate::qSlicerFEMesherModulePrivate() = default;

//-----------------------------------------------------------------------------
// qSlicerFEMesherModule methods

//-----------------------------------------------------------------------------
qSlicerFEMesherModule::qSlicerFEMesherModule(QObject* _parent)
  : Superclass(_parent)
  , d_ptr(new qSlicerFEMesherModulePrivate)
{
}

//-----------------------------------------------------------------------------
qSlicerFEMesherModule::~qSlicerFEMesherModule() = default;

//-----------------------------------------------------------------------------
QString qSlicerFEMesherModule::helpText() const
{
  return tr("Turns a segmentation or a label map into a conformal multi-material tetrahedral "
            "mesh for finite-element analysis: one mesh, tets labelled by material (cell array "
            "<i>labels</i>), neighbouring materials sharing the same interface triangles. "
            "Choose the materials and the element size, press Run, watch the particles settle, "
            "read the quality histograms and export for Abaqus/CalculiX, FEBio, Gmsh or VTK.");
}

//-----------------------------------------------------------------------------
QString qSlicerFEMesherModule::acknowledgementText() const
{
  return tr("Method after BioMesh3D's particle pipeline with the Integer Medial Axis; volume "
            "meshes by TetGen; surfaces with CGAL.");
}

//-----------------------------------------------------------------------------
QStringList qSlicerFEMesherModule::contributors() const
{
  QStringList moduleContributors;
  moduleContributors << QString("FEMesher developers");
  return moduleContributors;
}

//-----------------------------------------------------------------------------
QIcon qSlicerFEMesherModule::icon() const
{
  return QIcon(":/Icons/FEMesher.png");
}

//-----------------------------------------------------------------------------
QStringList qSlicerFEMesherModule::categories() const
{
  return QStringList() << "Segmentation";
}

//-----------------------------------------------------------------------------
QStringList qSlicerFEMesherModule::dependencies() const
{
  return QStringList() << "Segmentations";
}

//-----------------------------------------------------------------------------
void qSlicerFEMesherModule::setup()
{
  this->Superclass::setup();
}

//-----------------------------------------------------------------------------
qSlicerAbstractModuleRepresentation* qSlicerFEMesherModule::createWidgetRepresentation()
{
  return new qSlicerFEMesherModuleWidget;
}

//-----------------------------------------------------------------------------
vtkMRMLAbstractLogic* qSlicerFEMesherModule::createLogic()
{
  return vtkSlicerFEMesherLogic::New();
}
