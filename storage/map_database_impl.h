// Module-private (not part of storage's API): what the parts of MapDatabase share: the SQLite
// handle and its statement helpers (MapDatabase::Impl) and the stored format's limits. Used by
// map_database.cc (open, schema, migrations), map_database_impl.cc (the helpers),
// map_database_write.cc and map_database_read.cc. SQLite's header stays in the .cc files: its
// types are only declared here.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "storage/map_database.h"

struct sqlite3;
struct sqlite3_stmt;

namespace monoplane {
namespace map_database_internal {

// What a stored grid's cell size and a local map's side can be; other values come from a damaged
// file (and would overflow cell indices or allocate without bound).
constexpr double kMinStoredResolutionM = 1e-4;
constexpr double kMaxStoredResolutionM = 100.0;
constexpr int kMaxLocalMapSide = 1 << 14;

// The first schema version that stores floor features.
constexpr int kFloorFeaturesSchemaVersion = 2;
// The first schema version that stores moving objects.
constexpr int kMovingObjectsSchemaVersion = 3;

// The size of a file in bytes, -1 when it cannot be read.
std::int64_t FileSize(const std::string& path);

// RAII prepared statement.
class Statement {
 public:
  Statement() = default;
  ~Statement();
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;
  sqlite3_stmt** out() { return &stmt_; }
  sqlite3_stmt* get() const { return stmt_; }

 private:
  sqlite3_stmt* stmt_ = nullptr;
};

}  // namespace map_database_internal

struct MapDatabase::Impl {
  using Statement = map_database_internal::Statement;

  std::string path;
  Options options;
  sqlite3* db = nullptr;
  int schema_version = 0;
  std::optional<double> grid_resolution_m;
  bool read_only = false;
  int writer_lock_fd = -1;  // holds the map's one-writer lock (flock) while open for writing

  ~Impl();

  // THE helper every sqlite3 return code goes through: ok for OK/ROW/DONE, otherwise an error that
  // names the file, the cause users understand, what we were doing and SQLite's own words.
  StorageStatus Check(int rc, const char* context) const;

  StorageStatus Error(StorageErrorKind kind, const std::string& what) const {
    return {kind, path + ": " + what};
  }

  StorageStatus Exec(const char* sql, const char* context);

  StorageStatus Prepare(const char* sql, Statement* stmt, const char* context);

  // Steps a statement; *row tells whether a row is available.
  StorageStatus Step(const Statement& stmt, bool* row, const char* context);
  StorageStatus StepDone(const Statement& stmt, const char* context) {
    bool row = false;
    return Step(stmt, &row, context);
  }

  StorageStatus BindInt(const Statement& s, int i, std::int64_t v, const char* context);
  StorageStatus BindDouble(const Statement& s, int i, double v, const char* context);
  StorageStatus BindText(const Statement& s, int i, const std::string& v, const char* context);
  StorageStatus BindBlob(const Statement& s, int i, const void* data, std::size_t size,
                         const char* context);
  StorageStatus BindNull(const Statement& s, int i, const char* context);

  // A single integer from a query without parameters.
  StorageStatus QueryInt(const char* sql, std::int64_t* value, const char* context);

  StorageStatus CheckRun(std::int64_t run_id, const char* context);

  StorageStatus UpsertFrame(std::int64_t run_id, const FrameRecord& f, const Statement& s,
                            const char* context);

  // Within a keyframe's transaction: replaces its floor features by `blob` (EncodeFloorFeatures of
  // `features`), or deletes them when there are none.
  StorageStatus WriteFloorFeatures(std::int64_t run_id, std::int64_t frame_index,
                                   const FloorFeatures& features,
                                   const std::vector<std::uint8_t>& blob);

  StorageStatus ReadGridResolution();

  // Steps through every row of a statement, calling fn(stmt) -> StorageStatus for each.
  template <typename Fn>
  StorageStatus ForEachRow(const Statement& stmt, const char* context, Fn&& fn) {
    while (true) {
      bool row = false;
      StorageStatus st = Step(stmt, &row, context);
      if (!st.ok() || !row) return st;
      st = fn(stmt.get());
      if (!st.ok()) return st;
    }
  }

  // Runs fn() -> StorageStatus in one write transaction, after checking that the run exists
  // (run_id < 0: no run to check).
  template <typename Fn>
  StorageStatus InTransaction(std::int64_t run_id, const char* context, Fn&& fn);

  StorageStatus DecodeTileRow(const Statement& s, TiledGrid* grid);

  // Rolls back unless committed; BEGIN IMMEDIATE takes the write lock up front, so a second writer
  // waits (busy timeout) at the start instead of failing at commit.
  class Transaction {
   public:
    explicit Transaction(Impl* impl) : impl_(impl) {}
    ~Transaction();
    StorageStatus Begin(const char* context) {
      StorageStatus st = impl_->Exec("BEGIN IMMEDIATE", context);
      open_ = st.ok();
      return st;
    }
    StorageStatus Commit(const char* context) {
      StorageStatus st = impl_->Exec("COMMIT", context);
      if (st.ok()) open_ = false;
      return st;
    }

   private:
    Impl* impl_;
    bool open_ = false;
  };
};

template <typename Fn>
StorageStatus MapDatabase::Impl::InTransaction(std::int64_t run_id, const char* context, Fn&& fn) {
  Transaction tx(this);
  StorageStatus st = tx.Begin(context);
  if (st.ok() && run_id >= 0) st = CheckRun(run_id, context);
  if (st.ok()) st = fn();
  if (st.ok()) st = tx.Commit(context);
  return st;
}

}  // namespace monoplane
