#pragma once

#include <string>
#include <utility>

namespace monoplane {

// Why a storage call failed. Users see the message; programs may branch on the kind.
enum class StorageErrorKind {
  kOk = 0,
  kNotFound,         // no such file, or no such record (run, frame, octomap)
  kNotADatabase,     // the file is not an SQLite database
  kNotAMap,          // an SQLite database, but not a monoplane map
  kCorrupt,          // truncated or damaged database file
  kReadOnly,         // the file (or its folder) cannot be written
  kBusy,             // another process holds the lock longer than the busy timeout
  kDiskFull,         // no space left (or the configured page limit reached)
  kNewerSchema,      // written by a newer monoplane
  kInvalidArgument,  // the caller's values are unusable (unknown run, resolution mismatch, ...)
  kIo,               // any other I/O failure
  kInternal,         // a bug: SQL error, misuse
};

// A short lower-case name of a kind ("corrupt", "read-only", ...), for JSON and logs.
const char* StorageErrorKindName(StorageErrorKind kind);

// The outcome of a storage call: ok, or the kind of failure and a one-line message that names the
// file and the cause, e.g. "/maps/lab.db: not an SQLite database (file is not a database)".
class StorageStatus {
 public:
  StorageStatus() = default;
  StorageStatus(StorageErrorKind kind, std::string message)
      : kind_(kind), message_(std::move(message)) {}

  bool ok() const { return kind_ == StorageErrorKind::kOk; }
  StorageErrorKind kind() const { return kind_; }
  const std::string& message() const { return message_; }

 private:
  StorageErrorKind kind_ = StorageErrorKind::kOk;
  std::string message_;
};

}  // namespace monoplane
