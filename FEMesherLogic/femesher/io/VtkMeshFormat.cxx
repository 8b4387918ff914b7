// SPDX-License-Identifier: GPL-3.0-or-later
// VTK XML unstructured grid (.vtu) and legacy VTK (.vtk): VTK's own writers and readers on the
// grid of VtkConversion.h.
#include <femesher/io/MeshFormats.h>
#include <femesher/io/VtkConversion.h>

#include <vtkCallbackCommand.h>
#include <vtkCommand.h>
#include <vtkErrorCode.h>
#include <vtkLogger.h>
#include <vtkNew.h>
#include <vtkObjectFactory.h>
#include <vtkOutputWindow.h>
#include <vtkSmartPointer.h>
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

/// Collects what VTK would print (its executive's and helper objects' errors have no observer
/// of ours) instead of the coloured dump on the terminal.
class CollectingOutputWindow : public vtkOutputWindow {
 public:
  static CollectingOutputWindow* New();
  vtkTypeMacro(CollectingOutputWindow, vtkOutputWindow);
  void DisplayText(const char* text) override {
    if (text && collected.size() < 2000) collected += text;
  }
  std::string collected;
};
vtkStandardNewMacro(CollectingOutputWindow);

/// While it lives, VTK's messages go to a CollectingOutputWindow (the previous window after), and
/// vtkLogger, which VTK 9 also has print every error on stderr, prints nothing there.
class ScopedVtkOutput {
 public:
  ScopedVtkOutput()
      : previous_(vtkOutputWindow::GetInstance()),
        stderrVerbosity_(vtkLogger::GetCurrentVerbosityCutoff()) {
    vtkOutputWindow::SetInstance(window_);
    vtkLogger::SetStderrVerbosity(vtkLogger::VERBOSITY_OFF);
  }
  ~ScopedVtkOutput() {
    vtkLogger::SetStderrVerbosity(stderrVerbosity_);
    vtkOutputWindow::SetInstance(previous_);
  }
  ScopedVtkOutput(const ScopedVtkOutput&) = delete;
  ScopedVtkOutput& operator=(const ScopedVtkOutput&) = delete;
  const std::string& text() const { return window_->collected; }

 private:
  vtkSmartPointer<vtkOutputWindow> previous_;
  vtkLogger::Verbosity stderrVerbosity_;
  vtkNew<CollectingOutputWindow> window_;
};

/// The outcome of a VTK writer's Write(): OK, or WriteFailed naming `path` and the cause from
/// the writer's error code (else VTK's first message), on one line.
Status vtkWriteStatus(vtkAlgorithm* writer, int written, const std::string& path,
                      const std::string& messages) {
  const unsigned long code = writer->GetErrorCode();
  if (written == 1 && code == vtkErrorCode::NoError && messages.empty()) return Status::ok();
  std::string cause;
  if (code == vtkErrorCode::OutOfDiskSpaceError)
    cause = "the disk is full (or a file size limit was reached). Free some space or write to "
            "another disk.";
  else if (code == vtkErrorCode::CannotOpenFileError)
    cause = "the file cannot be created. Check that the folder is writable.";
  else
    cause = (messages.empty() ? std::string("VTK's writer failed")
                              : "VTK: " + oneLine(messages.substr(0, 200))) +
            ". Check the free space and that the folder is writable.";
  return {ErrorCode::WriteFailed, "Cannot write '" + path + "': " + cause};
}

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
    ScopedVtkOutput output;
    const int written = w->Write();
    return vtkWriteStatus(w, written, path, messages.text + output.text());
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
    ScopedVtkOutput output;
    const int written = w->Write();
    return vtkWriteStatus(w, written, path, messages.text + output.text());
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
