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

// VTK includes
#include <vtkAssignAttribute.h>
#include <vtkCellArray.h>
#include <vtkCellData.h>
#include <vtkImageData.h>
#include <vtkIntArray.h>
#include <vtkMatrix4x4.h>
#include <vtkNew.h>
#include <vtkObjectFactory.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkStringArray.h>
#include <vtkUnstructuredGrid.h>

// STD includes
#include <algorithm>
#include <cassert>
#include <cmath>
#include <set>

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
                                                         femesher::LabelVolume& out)
{
  if (!image || !image->GetPointData() || !image->GetPointData()->GetScalars())
  {
    return "The label map has no image data.";
  }
  vtkDataArray* scalars = image->GetPointData()->GetScalars();
  if (scalars->GetNumberOfComponents() != 1)
  {
    return "The label map has several components per voxel; one label per voxel is needed.";
  }
  int extent[6];
  image->GetExtent(extent);
  out = femesher::LabelVolume();
  for (int a = 0; a < 3; ++a)
  {
    out.dims[a] = extent[2 * a + 1] - extent[2 * a] + 1;
  }
  // IJK -> LPS = diag(-1, -1, 1) * IJK -> RAS.
  for (int c = 0; c < 3; ++c)
  {
    double column[3];
    for (int r = 0; r < 3; ++r)
    {
      column[r] = ijkToRas->GetElement(r, c) * (r < 2 ? -1.0 : 1.0);
    }
    const double norm = std::sqrt(column[0] * column[0] + column[1] * column[1] + column[2] * column[2]);
    if (norm <= 0)
    {
      return "The label map's IJK to RAS matrix is singular.";
    }
    out.spacing[c] = norm;
    for (int r = 0; r < 3; ++r)
    {
      out.direction[3 * r + c] = column[r] / norm;
    }
  }
  // Origin: the centre of the first voxel of the extent.
  const double ijk[4] = {double(extent[0]), double(extent[2]), double(extent[4]), 1.0};
  double ras[4];
  ijkToRas->MultiplyPoint(ijk, ras);
  out.origin = {{-ras[0], -ras[1], ras[2]}};
  const vtkIdType n = scalars->GetNumberOfTuples();
  out.labels.resize(size_t(n));
  std::set<int32_t> present;
  for (vtkIdType i = 0; i < n; ++i)
  {
    const double v = scalars->GetTuple1(i);
    if (v != std::floor(v) || std::abs(v) > 2147483647.0)
    {
      return "The volume holds non-integer values: it is not a label map.";
    }
    out.labels[size_t(i)] = int32_t(v);
    if (v != 0)
    {
      present.insert(int32_t(v));
    }
  }
  for (int32_t id : present)
  {
    femesher::Material m;
    m.id = id;
    m.name = "label " + std::to_string(id);
    m.color = femesher::defaultLabelColor(id);
    out.materials.push_back(m);
  }
  if (present.empty())
  {
    return "The label map is empty (only background).";
  }
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
  std::string error = LabelVolumeFromImage(node->GetImageData(), ijkToRas, out);
  if (!error.empty())
  {
    return std::string(node->GetName() ? node->GetName() : "label map") + ": " + error;
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
    error = LabelVolumeFromImage(labelmap->GetImageData(), ijkToRas, out);
  }
  this->GetMRMLScene()->RemoveNode(labelmap);
  if (!error.empty())
  {
    return std::string(node->GetName() ? node->GetName() : "segmentation") + ": " + error;
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
void vtkSlicerFEMesherLogic::MeshToUnstructuredGrid(const femesher::TetMesh& mesh, vtkUnstructuredGrid* grid)
{
  vtkNew<vtkPoints> points;
  points->SetDataTypeToDouble();
  points->SetNumberOfPoints(vtkIdType(mesh.points.size()));
  for (size_t i = 0; i < mesh.points.size(); ++i)
  {
    // LPS -> RAS. A rotation by 180 degrees about S: tets keep their orientation.
    points->SetPoint(vtkIdType(i), -mesh.points[i][0], -mesh.points[i][1], mesh.points[i][2]);
  }
  vtkNew<vtkCellArray> cells;
  vtkNew<vtkIntArray> labels;
  labels->SetName("labels");
  labels->SetNumberOfTuples(vtkIdType(mesh.tets.size()));
  for (size_t t = 0; t < mesh.tets.size(); ++t)
  {
    const vtkIdType ids[4] = {mesh.tets[t][0], mesh.tets[t][1], mesh.tets[t][2], mesh.tets[t][3]};
    cells->InsertNextCell(4, ids);
    labels->SetValue(vtkIdType(t), mesh.tetLabels[t]);
  }
  grid->Initialize();
  grid->SetPoints(points);
  grid->SetCells(VTK_TETRA, cells);
  grid->GetCellData()->AddArray(labels);
  grid->GetCellData()->SetActiveScalars("labels");
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
  vtkNew<vtkUnstructuredGrid> grid;
  MeshToUnstructuredGrid(mesh, grid);
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
