// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/Status.h>

namespace femesher {

const char* errorCodeName(ErrorCode code) {
  switch (code) {
    case ErrorCode::Ok: return "ok";
    case ErrorCode::InvalidArgument: return "invalid-argument";
    case ErrorCode::FileNotFound: return "file-not-found";
    case ErrorCode::UnreadableFile: return "unreadable-file";
    case ErrorCode::CorruptFile: return "corrupt-file";
    case ErrorCode::NotALabelMap: return "not-a-label-map";
    case ErrorCode::EmptyLabelMap: return "empty-label-map";
    case ErrorCode::TooManyLabels: return "too-many-labels";
    case ErrorCode::OverlappingSegments: return "overlapping-segments";
    case ErrorCode::MeshingFailed: return "meshing-failed";
    case ErrorCode::WriteFailed: return "write-failed";
    case ErrorCode::Canceled: return "canceled";
    case ErrorCode::Internal: return "internal-error";
  }
  return "unknown";
}

}  // namespace femesher
