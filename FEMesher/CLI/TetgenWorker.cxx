// SPDX-License-Identifier: GPL-3.0-or-later
// femesher-tetgen-worker: the helper process the VolumeMesh stage runs each TetGen job in (a
// fresh process instead of a fork of the whole run; see stages/internal/TetgenJobs.h). Built from
// TetgenProcess.cxx and TetGen alone, so that it starts at a few MB.
#include <femesher/stages/internal/TetgenProcess.h>

int main(int argc, char** argv) { return femesher::volume_detail::tetgenWorkerMain(argc, argv); }
