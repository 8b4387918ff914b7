// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file PanelWait.h
/// Shared by the widget tests: a run long enough to cancel, and waiting on a panel's run while the
/// event loop runs.

#include <qFEMesherPanelWidget.h>

#include <QDoubleSpinBox>
#include <QElapsedTimer>
#include <QtTest>

/// Processes events until `panel` is no longer running or `timeoutMs` passed, then `settleMs`
/// more (queued signals of the run's end); true when the run ended.
inline bool waitForPanelEnd(const qFEMesherPanelWidget& panel, int timeoutMs, int settleMs = 50) {
  QElapsedTimer t;
  t.start();
  while (panel.isRunning() && t.elapsed() < timeoutMs) QTest::qWait(20);
  QTest::qWait(settleMs);
  return !panel.isRunning();
}

/// Processes events until `reached()` holds or the run ended (at most `timeoutMs`); true when
/// `reached()` holds while the panel still runs. Unlike a QTRY, which waits three times its
/// timeout for a condition that cannot hold any more, it returns as soon as the run has ended.
template <class Condition>
bool waitWhileRunning(const qFEMesherPanelWidget& panel, Condition reached, int timeoutMs) {
  QElapsedTimer t;
  t.start();
  while (!reached() && panel.isRunning() && t.elapsed() < timeoutMs) QTest::qWait(20);
  return reached() && panel.isRunning();
}

/// Parameters of a run to cancel: the fine preset with a bound on the tet volume. The phantom's
/// fine run takes 1.3 s, 0.1 s of it the particle system; with the bound the stages after it take
/// ~15 s, far beyond a slow GUI tick (the cancel stops them; applyPreset lifts the bound).
inline bool useLongRun(qFEMesherPanelWidget& panel) {
  auto* bound =
      qobject_cast<QDoubleSpinBox*>(panel.parameterEditor(QStringLiteral("max_tet_volume")));
  if (!panel.applyPreset(QStringLiteral("fine")) || !bound) return false;
  bound->setValue(0.05);
  return true;
}
