// SPDX-License-Identifier: GPL-3.0-or-later

// FEMesher Logic includes
#include "vtkSlicerFEMesherLogic.h"

// Segmentations includes
#include <vtkSegment.h>
#include <vtkSegmentation.h>
#include <vtkSlicerSegmentationsModuleLogic.h>

// MRML includes
#include <vtkMRMLColorTableNode.h>
#include <vtkMRMLLabelMapVolumeNode.h>
#include <vtkMRMLModelDisplayNode.h>
#include <vtkMRMLModelNode.h>
#include <vtkMRMLScene.h>
#include <vtkMRMLSegmentationNode.h>
#include <vtkMRMLTransformNode.h>

// FEMesher includes
#include <femesher/io/VtkConversion.h>

// VTK includes
#include <vtkAssignAttribute.h>
#include <vtkIntArray.h>
#include <vtkMatrix4x4.h>
#include <vtkNew.h>
#include <vtkObjectFactory.h>
#include <vtkStringArray.h>
#include <vtkUnstructuredGrid.h>

// STD includes
#include <algorithm>
#include <cassert>
#include <utility>

//----------------------------------------------------------------------------
vtkStandardNewMacro(vtkSlicerFEMesherLogic);

//----------------------------------------------------------------------------
vtkSlicerFEMesherLogic::vtkSlicerFEMesherLogic() = default;

//----------------------------------------------------------------------------
vtkSlicerFEMesherLogic::~vtkSlicerFEMesherLogic() = default;

//----------------------------------------------------------------------------
void vtkSlicerFEMesherLogic::PrintSelf(ostream& os, vtkIndent indent)
{
  this->Superclass::PrintSelf(os, indent);
}

//---------------------------------------------------------------------------
void vtkSlicerFEMesherLogic::SetMRMLSceneInternal(vtkMRMLScene* newScene)
{
  vtkNew<vtkIntArray> events;
  events->InsertNextValue(vtkMRMLScene::NodeAddedEvent);
  events->InsertNextValue(vtkMRMLScene::NodeRemovedEvent);
  events->InsertNextValue(vtkMRMLScene::EndBatchProcessEvent);
  this->SetAndObserveMRMLSceneEventsInternal(newScene, events.GetPointer());
}

//-----------------------------------------------------------------------------
void vtkSlicerFEMesherLogic::RegisterNodes()
{
  assert(this->GetMRMLScene() != 0);
}

//---------------------------------------------------------------------------
void vtkSlicerFEMesherLogic::UpdateFromMRMLScene()
{
  assert(this->GetMRMLScene() != 0);
}

//---------------------------------------------------------------------------
void vtkSlicerFEMesherLogic::OnMRMLSceneNodeAdded(vtkMRMLNode* vtkNotUsed(node))
{
}

//---------------------------------------------------------------------------
void vtkSlicerFEMesherLogic::OnMRMLSceneNodeRemoved(vtkMRMLNode* vtkNotUsed(node))
{
}

//---------------------------------------------------------------------------
std::string vtkSlicerFEMesherLogic::LabelVolumeFromNode(vtkMRMLNode* node, femesher::LabelVolume& out)
{
  if (auto* seg = vtkMRMLSegmentationNode::SafeDownCast(node))
  {
    return this->LabelVolumeFromSegmentationNode(seg, out);
  }
  if (auto* labels = vtkMRMLLabelMapVolumeNode::SafeDownCast(node))
  {
    return this->LabelVolumeFromLabelMapNode(labels, out);
  }
  return "FEMesher needs a segmentation or a label map volume as input.";
}

//---------------------------------------------------------------------------
std::string vtkSlicerFEMesherLogic::LabelVolumeFromImage(vtkImageData* image, vtkMatrix4x4* ijkToRas,
                                                         const std::string& name,
                                                         femesher::LabelVolume& out)
{
  femesher::Result<femesher::LabelVolume> volume =
    femesher::labelVolumeFromVtkImage(image, ijkToRas, femesher::VtkFrame::RAS, name);
  if (!volume)
  {
    return volume.status().message();
  }
  out = std::move(volume).value();
  return std::string();
}

//---------------------------------------------------------------------------
std::string vtkSlicerFEMesherLogic::LabelVolumeFromLabelMapNode(vtkMRMLLabelMapVolumeNode* node,
                                                                femesher::LabelVolume& out)
{
  if (!node)
  {
    return "No label map given.";
  }
  vtkNew<vtkMatrix4x4> ijkToRas;
  node->GetIJKToRASMatrix(ijkToRas);
  if (vtkMRMLTransformNode* parent = node->GetParentTransformNode())
  {
    vtkNew<vtkMatrix4x4> toWorld;
    if (!parent->IsTransformToWorldLinear())
    {
      return "The label map is under a non-linear transform: harden the transform first.";
    }
    parent->GetMatrixTransformToWorld(toWorld);
    vtkMatrix4x4::Multiply4x4(toWorld, ijkToRas, ijkToRas);
  }
  const std::string error = LabelVolumeFromImage(
    node->GetImageData(), ijkToRas, node->GetName() ? node->GetName() : "label map", out);
  if (!error.empty())
  {
    return error;
  }
  if (vtkMRMLColorNode* colors = node->GetDisplayNode() ? node->GetDisplayNode()->GetColorNode() : nullptr)
  {
    for (femesher::Material& m : out.materials)
    {
      if (const char* name = colors->GetColorName(m.id))
      {
        if (*name)
        {
          m.name = name;
        }
      }
      double rgba[4];
      if (colors->GetColor(m.id, rgba))
      {
        m.color = {{rgba[0], rgba[1], rgba[2]}};
      }
    }
  }
  out.sourcePath = node->GetName() ? node->GetName() : "";
  return std::string();
}

//---------------------------------------------------------------------------
std::string vtkSlicerFEMesherLogic::LabelVolumeFromSegmentationNode(vtkMRMLSegmentationNode* node,
                                                                    femesher::LabelVolume& out)
{
  if (!node || !node->GetSegmentation() || !this->GetMRMLScene())
  {
    return "No segmentation given.";
  }
  vtkSegmentation* segmentation = node->GetSegmentation();
  vtkNew<vtkStringArray> segmentIds;
  segmentation->GetSegmentIDs(segmentIds);
  if (segmentIds->GetNumberOfValues() == 0)
  {
    return "The segmentation has no segments.";
  }
  // A temporary label map: segment i -> label i + 1 (parent transforms are applied by the export).
  vtkMRMLLabelMapVolumeNode* labelmap = vtkMRMLLabelMapVolumeNode::SafeDownCast(
    this->GetMRMLScene()->AddNewNodeByClass("vtkMRMLLabelMapVolumeNode", "FEMesherInput"));
  std::string error;
  if (!vtkSlicerSegmentationsModuleLogic::ExportSegmentsToLabelmapNode(
        node, segmentIds, labelmap, nullptr, vtkSegmentation::EXTENT_UNION_OF_EFFECTIVE_SEGMENTS))
  {
    error = "Could not export the segments to a label map (do segments overlap?).";
  }
  else
  {
    vtkNew<vtkMatrix4x4> ijkToRas;
    labelmap->GetIJKToRASMatrix(ijkToRas);
    error = LabelVolumeFromImage(
      labelmap->GetImageData(), ijkToRas, node->GetName() ? node->GetName() : "segmentation", out);
  }
  this->GetMRMLScene()->RemoveNode(labelmap);
  if (!error.empty())
  {
    return error;
  }
  for (femesher::Material& m : out.materials)
  {
    const int index = m.id - 1;
    if (index < 0 || index >= segmentIds->GetNumberOfValues())
    {
      continue;
    }
    if (vtkSegment* segment = segmentation->GetSegment(segmentIds->GetValue(index)))
    {
      m.name = segment->GetName() ? segment->GetName() : m.name;
      const double* c = segment->GetColor();
      m.color = {{c[0], c[1], c[2]}};
    }
  }
  out.sourcePath = node->GetName() ? node->GetName() : "";
  return std::string();
}

//---------------------------------------------------------------------------
vtkMRMLModelNode* vtkSlicerFEMesherLogic::UpdateModelNodeFromMesh(const femesher::TetMesh& mesh,
                                                                  vtkMRMLModelNode* model)
{
  vtkMRMLScene* scene = this->GetMRMLScene();
  if (!scene)
  {
    vtkErrorMacro("UpdateModelNodeFromMesh: no scene");
    return nullptr;
  }
  if (!model)
  {
    model = vtkMRMLModelNode::SafeDownCast(scene->AddNewNodeByClass("vtkMRMLModelNode", "FEMesh"));
  }
  // LPS -> RAS, cell array "labels" (femesher/io/VtkConversion.h).
  femesher::VtkGridOptions gridOptions;
  gridOptions.frame = femesher::VtkFrame::RAS;
  vtkNew<vtkUnstructuredGrid> grid;
  femesher::meshToVtkGrid(mesh, grid, gridOptions);
  model->SetAndObserveMesh(grid);
  if (!model->GetDisplayNode())
  {
    model->CreateDefaultDisplayNodes();
  }
  vtkMRMLModelDisplayNode* display = vtkMRMLModelDisplayNode::SafeDownCast(model->GetDisplayNode());
  if (!display)
  {
    return model;
  }
  // A colour table with the materials' colours, indexed by label.
  int maxLabel = 0;
  for (const femesher::Material& m : mesh.materials)
  {
    maxLabel = std::max(maxLabel, int(m.id));
  }
  vtkMRMLColorTableNode* colors = vtkMRMLColorTableNode::SafeDownCast(
    scene->AddNewNodeByClass("vtkMRMLColorTableNode", std::string(model->GetName()) + "_materials"));
  colors->SetTypeToUser();
  colors->SetNumberOfColors(maxLabel + 1);
  colors->SetColor(0, "background", 0.0, 0.0, 0.0, 0.0);
  for (const femesher::Material& m : mesh.materials)
  {
    if (m.id >= 0)
    {
      colors->SetColor(m.id, m.name.c_str(), m.color[0], m.color[1], m.color[2], 1.0);
    }
  }
  colors->SetNamesInitialised(true);
  display->SetAndObserveColorNodeID(colors->GetID());
  display->SetActiveScalar("labels", vtkAssignAttribute::CELL_DATA);
  display->SetScalarRangeFlag(vtkMRMLDisplayNode::UseColorNodeScalarRange);
  display->SetScalarVisibility(true);
  display->SetEdgeVisibility(true);
  display->SetVisibility2D(true);
  return model;
}
