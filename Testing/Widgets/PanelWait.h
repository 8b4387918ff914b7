// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file PanelWait.h
/// Shared by the widget tests: waiting for a panel's run to end while the event loop runs.

#include <qFEMesherPanelWidget.h>

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
