// SPDX-License-Identifier: GPL-3.0-or-later
// VTK XML unstructured grid (.vtu) and legacy VTK (.vtk): VTK's own writers and readers on the
// grid of VtkConversion.h.
#include <femesher/io/MeshFormats.h>
#include <femesher/io/VtkConversion.h>

#include <vtkCallbackCommand.h>
#include <vtkCommand.h>
#include <vtkNew.h>
#include <vtkUnstructuredGrid.h>
#include <vtkUnstructuredGridReader.h>
#include <vtkUnstructuredGridWriter.h>
#include <vtkXMLUnstructuredGridReader.h>
#include <vtkXMLUnstructuredGridWriter.h>

namespace femesher::meshio {

namespace {

/// Collects VTK error/warning messages instead of letting VTK print them.
class VtkMessages {
 public:
  explicit VtkMessages(vtkObject* obj) {
    cb_->SetClientData(this);
    cb_->SetCallback([](vtkObject*, unsigned long, void* self, void* data) {
      auto* me = static_cast<VtkMessages*>(self);
      if (data && me->text.size() < 2000) me->text += std::string(static_cast<const char*>(data));
    });
    obj->AddObserver(vtkCommand::ErrorEvent, cb_);
    obj->AddObserver(vtkCommand::WarningEvent, cb_);
  }
  vtkCommand* command() { return cb_; }
  std::string text;

 private:
  vtkNew<vtkCallbackCommand> cb_;
};

}  // namespace

Status writeVtu(const TetMesh& m, const std::string& path, const ExportOptions& o) {
  vtkNew<vtkUnstructuredGrid> ug;
  meshToVtkGrid(
      m, ug,
      {VtkFrame::LPS, /*fieldData=*/true, o.provenance, o.elementOrder, o.midEdgeNodes.get()});
  return writeAtomically(path, [&](const std::string& tmp) {
    vtkNew<vtkXMLUnstructuredGridWriter> w;
    VtkMessages messages(w);
    w->SetFileName(tmp.c_str());
    w->SetInputData(ug);
    w->SetDataModeToAppended();
    w->SetCompressorTypeToZLib();
    if (w->Write() != 1 || !messages.text.empty()) return ioError(path);
    return Status::ok();
  });
}

/// Legacy VTK 4.2 with Slicer's header convention ("3D Slicer output. SPACE=LPS"), which Slicer
/// reads to place the mesh; read by ParaView and meshio too.
Status writeLegacyVtk(const TetMesh& m, const std::string& path, const ExportOptions& o) {
  vtkNew<vtkUnstructuredGrid> ug;
  meshToVtkGrid(m, ug,
                {VtkFrame::LPS, /*fieldData=*/false, "", o.elementOrder, o.midEdgeNodes.get()});
  return writeAtomically(path, [&](const std::string& tmp) {
    vtkNew<vtkUnstructuredGridWriter> w;
    VtkMessages messages(w);
    w->SetFileName(tmp.c_str());
    w->SetInputData(ug);
    w->SetFileVersion(42);
    w->SetFileTypeToBinary();
    w->SetHeader("3D Slicer output. SPACE=LPS");
    if (w->Write() != 1 || !messages.text.empty()) return ioError(path);
    return Status::ok();
  });
}

Result<TetMesh> readVtu(const std::string& path, std::vector<std::array<int32_t, 6>>* midNodes) {
  vtkNew<vtkXMLUnstructuredGridReader> r;
  VtkMessages messages(r);
  r->SetReaderErrorObserver(messages.command());
  r->SetParserErrorObserver(messages.command());  // the XML parser's own errors (damaged data)
  if (!r->CanReadFile(path.c_str()))
    return fail(ErrorCode::UnreadableFile, path, "it is not a VTK XML unstructured grid (.vtu).");
  r->SetFileName(path.c_str());
  r->Update();
  if (!messages.text.empty() || r->GetErrorCode() != 0)
    return fail(ErrorCode::CorruptFile, path,
                "VTK could not decode it (truncated or damaged?)" +
                    (messages.text.empty() ? std::string(".") : ": " + oneLine(messages.text.substr(0, 300))));
  return vtkGridToMesh(r->GetOutput(), path, VtkFrame::LPS, midNodes);
}

Result<TetMesh> readLegacyVtk(const std::string& path,
                              std::vector<std::array<int32_t, 6>>* midNodes) {
  vtkNew<vtkUnstructuredGridReader> r;
  VtkMessages messages(r);
  r->SetFileName(path.c_str());
  if (!r->IsFileUnstructuredGrid())
    return fail(ErrorCode::UnreadableFile, path, "it is not a legacy VTK unstructured grid.");
  r->Update();
  if (!messages.text.empty())
    return fail(ErrorCode::CorruptFile, path,
                "VTK could not decode it: " + oneLine(messages.text.substr(0, 300)));
  return vtkGridToMesh(r->GetOutput(), path, VtkFrame::LPS, midNodes);
}

}  // namespace femesher::meshio
