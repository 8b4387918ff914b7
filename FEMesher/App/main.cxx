// SPDX-License-Identifier: GPL-3.0-or-later
// FEMesherApp: open a segmentation, mesh it, look at the mesh and its quality, export it.
// Scripted use: FEMesherApp --open FILE | --sample [--preset NAME] [--parameters FILE]
//               [--run] [--screenshot OUT.png] [--screenshot-dir DIR] [--export MESH]... [--exit]
#include "qFEMesherMainWindow.h"

#include <femesher/Version.h>

#include <QApplication>
#include <QCommandLineParser>
#include <QSurfaceFormat>
#include <QVTKOpenGLNativeWidget.h>

int main(int argc, char* argv[]) {
  // Must precede QApplication so every OpenGL context VTK gets has the right format.
  QSurfaceFormat::setDefaultFormat(QVTKOpenGLNativeWidget::defaultFormat());
  QApplication::setAttribute(Qt::AA_ShareOpenGLContexts);
  QApplication app(argc, argv);
  QApplication::setApplicationName(QStringLiteral("FEMesherApp"));
  QApplication::setOrganizationName(QStringLiteral("FEMesher"));
  QApplication::setApplicationVersion(QStringLiteral(FEMESHER_VERSION));
  QApplication::setWindowIcon(QIcon(QStringLiteral(":/Icons/FEMesher.png")));

  QCommandLineParser parser;
  parser.setApplicationDescription(QStringLiteral(
      "FEMesher: conformal multi-material tetrahedral meshes from labelled volumes."));
  parser.addHelpOption();
  parser.addVersionOption();
  const QCommandLineOption open(QStringList{"o", "open"}, "Open this label map.", "FILE");
  const QCommandLineOption sample("sample", "Open the built-in phantom (a femur with an implant).");
  const QCommandLineOption preset("preset", "Preset: coarse, default or fine.", "NAME");
  const QCommandLineOption params("parameters", "Load a JSON parameter file (as the CLI's).", "FILE");
  const QCommandLineOption run("run", "Start meshing once the file is open.");
  const QCommandLineOption shot("screenshot", "Save a picture of the window after the run.", "PNG");
  const QCommandLineOption shotDir(
      "screenshot-dir",
      "Save 01_before_run.png, 02_mid_run.png, 03_final_clipped.png, 04_histograms.png here.",
      "DIR");
  const QCommandLineOption exportMesh("export", "After a successful run, export the mesh (repeatable).",
                                      "MESH");
  const QCommandLineOption exitOpt("exit", "Quit when done (exit code 0 only if all went well).");
  const QCommandLineOption size("size", "Window size WxH (default 1600x1000).", "WxH", "1600x1000");
  parser.addOptions({open, sample, preset, params, run, shot, shotDir, exportMesh, exitOpt, size});
  parser.process(app);

  qFEMesherMainWindow::Script script;
  script.open = parser.value(open);
  script.sample = parser.isSet(sample);
  script.preset = parser.value(preset);
  script.parameters = parser.value(params);
  script.run = parser.isSet(run);
  script.screenshot = parser.value(shot);
  script.screenshotDir = parser.value(shotDir);
  script.exports = parser.values(exportMesh);
  script.exit = parser.isSet(exitOpt);

  qFEMesherMainWindow window;
  const QStringList wh = parser.value(size).split('x');
  if (wh.size() == 2) window.resize(wh[0].toInt(), wh[1].toInt());
  window.show();
  window.startScript(script);
  return app.exec();
}
