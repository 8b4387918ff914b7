// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file Status.h
/// Typed errors for FEMesher. Nothing in the library calls exit() or prints: every failure is an
/// `ErrorCode` plus a message a clinician can act on (which file, what is wrong, what to do).
/// Library code may throw `femesher::Error` internally; every public entry point that can fail
/// returns `Status` or `Result<T>` instead. The CLI maps each code to its own exit code
/// (`exitCodeFor`), listed in the README.

#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <variant>

namespace femesher {

/// Error classes. The numeric value is the CLI exit code (0 = success).
enum class ErrorCode : int {
  Ok = 0,
  InvalidArgument = 2,     ///< bad command line, unknown parameter, value out of range
  FileNotFound = 3,        ///< input path does not exist
  UnreadableFile = 4,      ///< exists but cannot be read/decoded (unknown format, permissions)
  CorruptFile = 5,         ///< truncated data, header that lies about its data
  NotALabelMap = 6,        ///< float values that are not integers, 2-D image, vector pixels
  EmptyLabelMap = 7,       ///< only background, or nothing left after min_voxels
  TooManyLabels = 8,       ///< more than 65,535 distinct labels
  OverlappingSegments = 9, ///< .seg.nrrd with segments overlapping in several layers
  MeshingFailed = 10,      ///< a meshing stage could not produce a valid mesh
  WriteFailed = 11,        ///< output could not be written
  Canceled = 12,           ///< the run was canceled by the user
  Internal = 13,           ///< a bug: please report it
};

/// Short stable name of a code ("file-not-found"), used in JSON reports.
const char* errorCodeName(ErrorCode code);

/// Exit code the CLI uses for `code`.
inline int exitCodeFor(ErrorCode code) { return static_cast<int>(code); }

/// Success or an error code with a human-readable message.
class Status {
 public:
  Status() = default;
  Status(ErrorCode code, std::string message) : code_(code), message_(std::move(message)) {}
  static Status ok() { return {}; }

  bool isOk() const { return code_ == ErrorCode::Ok; }
  explicit operator bool() const { return isOk(); }
  ErrorCode code() const { return code_; }
  const std::string& message() const { return message_; }

 private:
  ErrorCode code_ = ErrorCode::Ok;
  std::string message_;
};

/// Exception used inside the library; converted to Status at public boundaries.
class Error : public std::runtime_error {
 public:
  Error(ErrorCode code, const std::string& message) : std::runtime_error(message), code_(code) {}
  ErrorCode code() const { return code_; }
  Status status() const { return {code_, what()}; }

 private:
  ErrorCode code_;
};

/// A value or an error Status.
template <class T>
class Result {
 public:
  Result(T value) : data_(std::move(value)) {}  // NOLINT(google-explicit-constructor)
  Result(Status status) : data_(std::move(status)) {  // NOLINT(google-explicit-constructor)
    if (std::get<Status>(data_).isOk())
      data_ = Status(ErrorCode::Internal, "Result constructed from an OK status without a value");
  }
  Result(ErrorCode code, std::string message) : data_(Status(code, std::move(message))) {}

  bool isOk() const { return std::holds_alternative<T>(data_); }
  explicit operator bool() const { return isOk(); }
  const Status& status() const {
    static const Status okStatus;
    return isOk() ? okStatus : std::get<Status>(data_);
  }
  T& value() & {
    if (!isOk()) throw Error(status().code(), status().message());
    return std::get<T>(data_);
  }
  const T& value() const& {
    if (!isOk()) throw Error(status().code(), status().message());
    return std::get<T>(data_);
  }
  T&& value() && {
    if (!isOk()) throw Error(status().code(), status().message());
    return std::get<T>(std::move(data_));
  }
  T* operator->() { return &value(); }
  const T* operator->() const { return &value(); }

 private:
  std::variant<T, Status> data_;
};

}  // namespace femesher
