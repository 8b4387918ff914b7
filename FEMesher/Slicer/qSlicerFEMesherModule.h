// SPDX-License-Identifier: GPL-3.0-or-later
#ifndef __qSlicerFEMesherModule_h
#define __qSlicerFEMesherModule_h

// Slicer includes
#include "qSlicerLoadableModule.h"

#include "qSlicerFEMesherModuleExport.h"

class qSlicerFEMesherModulePrivate;

/// FEMesher as a Slicer loadable module (the Slicer adapter; see DESIGN.md, SLICER.md).
class Q_SLICER_QTMODULES_FEMESHER_EXPORT qSlicerFEMesherModule : public qSlicerLoadableModule
{
  Q_OBJECT
  Q_PLUGIN_METADATA(IID "org.slicer.modules.loadable.qSlicerLoadableModule/1.0");
  Q_INTERFACES(qSlicerLoadableModule);

public:
  typedef qSlicerLoadableModule Superclass;
  explicit qSlicerFEMesherModule(QObject* parent = nullptr);
  ~qSlicerFEMesherModule() override;

  qSlicerGetTitleMacro(tr("FEMesher"));

  QString helpText() const override;
  QString acknowledgementText() const override;
  QStringList contributors() const override;

  QIcon icon() const override;

  QStringList categories() const override;
  QStringList dependencies() const override;

protected:
  /// Initialize the module. Register the volumes reader/writer
  void setup() override;

  /// Create and return the widget representation associated to this module
  qSlicerAbstractModuleRepresentation* createWidgetRepresentation() override;

  /// Create and return the logic associated to this module
  vtkMRMLAbstractLogic* createLogic() override;

protected:
  QScopedPointer<qSlicerFEMesherModulePrivate> d_ptr;

private:
  Q_DECLARE_PRIVATE(qSlicerFEMesherModule);
  Q_DISABLE_COPY(qSlicerFEMesherModule);
};

#endif
