// SPDX-License-Identifier: GPL-3.0-or-later
// .NAME vtkSlicerFEMesherLogic - slicer logic class for the FEMesher module
// .SECTION Description
// The only FEMesher code that knows MRML and RAS. It converts a segmentation or a label map
// volume node (RAS) into femesher::LabelVolume (LPS, what FEMesherLogic works in), and a
// femesher::TetMesh (LPS) into a model node (RAS) holding a vtkUnstructuredGrid with the cell
// array "labels" and a colour table of the materials. All meshing is done by FEMesherLogic
// (through the panel's worker thread); this class must be called on the main thread.

#ifndef __vtkSlicerFEMesherLogic_h
#define __vtkSlicerFEMesherLogic_h

// Slicer includes
#include "vtkSlicerModuleLogic.h"

// FEMesher includes
#include <femesher/Types.h>

// STD includes
#include <cstdlib>
#include <string>

#include "vtkSlicerFEMesherModuleLogicExport.h"

class vtkImageData;
class vtkMatrix4x4;
class vtkMRMLColorNode;
class vtkMRMLLabelMapVolumeNode;
class vtkMRMLModelNode;
class vtkMRMLNode;
class vtkMRMLSegmentationNode;

class VTK_SLICER_FEMESHER_MODULE_LOGIC_EXPORT vtkSlicerFEMesherLogic :
  public vtkSlicerModuleLogic
{
public:

  static vtkSlicerFEMesherLogic *New();
  vtkTypeMacro(vtkSlicerFEMesherLogic, vtkSlicerModuleLogic);
  void PrintSelf(ostream& os, vtkIndent indent) override;

  /// Segmentation or label map node -> LPS label volume. Returns "" on success, else a message.
  std::string LabelVolumeFromNode(vtkMRMLNode* node, femesher::LabelVolume& out);
  /// Label map volume: geometry from IJKToRAS (and a linear parent transform), material names and
  /// colours from its colour node.
  std::string LabelVolumeFromLabelMapNode(vtkMRMLLabelMapVolumeNode* node,
                                          femesher::LabelVolume& out);
  /// Segmentation: all segments merged into one label map (segment i -> label i+1, which requires
  /// non-overlapping segments), names and colours from the segments.
  std::string LabelVolumeFromSegmentationNode(vtkMRMLSegmentationNode* node,
                                              femesher::LabelVolume& out);

  /// Image + IJK->RAS matrix -> LPS label volume, converted and checked by FEMesherLogic
  /// (femesher::labelVolumeFromVtkImage: the same label-map checks as for files). `name` (the
  /// node's) starts every message.
  static std::string LabelVolumeFromImage(vtkImageData* image, vtkMatrix4x4* ijkToRas,
                                          const std::string& name, femesher::LabelVolume& out);

  /// Put the mesh into `model` (created in the scene when null), coloured by material.
  vtkMRMLModelNode* UpdateModelNodeFromMesh(const femesher::TetMesh& mesh, vtkMRMLModelNode* model);

protected:
  vtkSlicerFEMesherLogic();
  ~vtkSlicerFEMesherLogic() override;

  void SetMRMLSceneInternal(vtkMRMLScene* newScene) override;
  /// Register MRML Node classes to Scene. Gets called automatically when the MRMLScene is attached to this logic class.
  void RegisterNodes() override;
  void UpdateFromMRMLScene() override;
  void OnMRMLSceneNodeAdded(vtkMRMLNode* node) override;
  void OnMRMLSceneNodeRemoved(vtkMRMLNode* node) override;
private:

  vtkSlicerFEMesherLogic(const vtkSlicerFEMesherLogic&); // Not implemented
  void operator=(const vtkSlicerFEMesherLogic&); // Not implemented
};

#endif
