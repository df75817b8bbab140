// The catalogue's SQLite handle (server/store/ only): one sqlite3 connection with a cache of
// prepared statements, statements with typed binds and reads, and BEGIN IMMEDIATE transactions.
#pragma once

#include <sqlite3.h>

#include <cstdint>
#include <cstring>
#include <string>
#include <unordered_map>
#include <vector>

#include "server/store/catalogue.hpp"

namespace softshock::server {

// One sqlite3 handle with a cache of prepared statements. Not thread-safe by itself: the
// Catalogue holds the matching mutex around every use.
namespace detail {

inline std::string blob_of(const std::vector<double>& v) {
  return std::string(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(double));
}

class SqliteConnection {
 public:
  explicit SqliteConnection(const std::string& path) {
    const int rc =
        sqlite3_open_v2(path.c_str(), &db_,
                        SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX, nullptr);
    if (rc != SQLITE_OK) {
      std::string msg = db_ ? sqlite3_errmsg(db_) : sqlite3_errstr(rc);
      sqlite3_close(db_);
      throw CatalogueError("cannot open " + path + ": " + msg);
    }
    // Waiting writers (another process, a checkpoint) retry for up to 5 s instead of failing.
    sqlite3_busy_timeout(db_, 5000);
    exec("PRAGMA foreign_keys = ON");
  }
  ~SqliteConnection() {
    for (auto& [sql, stmt] : cache_) sqlite3_finalize(stmt);
    sqlite3_close(db_);
  }

  void exec(const char* sql) {
    char* err = nullptr;
    if (const int rc = sqlite3_exec(db_, sql, nullptr, nullptr, &err); rc != SQLITE_OK) {
      std::string msg = err ? err : "unknown error";
      sqlite3_free(err);
      throw_error(rc, msg);
    }
  }

  // SQLITE_FULL (the disk, or the file system's quota) is CatalogueFull: a bound the client can
  // act on, not a broken store.
  [[noreturn]] static void throw_error(int rc, const std::string& message) {
    if ((rc & 0xff) == SQLITE_FULL) {
      throw CatalogueFull(
          "the daemon's disk is full: the catalogue cannot grow (" + message +
          "); delete jobs or meshes to make room, or ask the daemon's operator for space");
    }
    throw CatalogueError("sqlite: " + message);
  }

  class Stmt {
   public:
    Stmt(SqliteConnection& c, sqlite3_stmt* s) : c_(c), s_(s) {}
    ~Stmt() {
      sqlite3_reset(s_);
      sqlite3_clear_bindings(s_);
    }
    Stmt(const Stmt&) = delete;
    Stmt& operator=(const Stmt&) = delete;

    Stmt& bind(int i, int64_t v) {
      check(sqlite3_bind_int64(s_, i, v));
      return *this;
    }
    Stmt& bind(int i, int v) { return bind(i, static_cast<int64_t>(v)); }
    Stmt& bind(int i, double v) {
      check(sqlite3_bind_double(s_, i, v));
      return *this;
    }
    Stmt& bind(int i, const std::string& v) {
      check(sqlite3_bind_text(s_, i, v.data(), static_cast<int>(v.size()), SQLITE_TRANSIENT));
      return *this;
    }
    Stmt& bind_null(int i) {
      check(sqlite3_bind_null(s_, i));
      return *this;
    }
    Stmt& bind_blob(int i, const std::vector<double>& v) {
      const std::string b = blob_of(v);
      check(sqlite3_bind_blob(s_, i, b.data(), static_cast<int>(b.size()), SQLITE_TRANSIENT));
      return *this;
    }
    // true while rows come back.
    bool step() {
      const int rc = sqlite3_step(s_);
      if (rc == SQLITE_ROW) return true;
      if (rc == SQLITE_DONE) return false;
      throw_error(rc, sqlite3_errmsg(c_.db_));
    }
    void run() {
      while (step()) {
      }
    }
    int64_t i64(int col) const { return sqlite3_column_int64(s_, col); }
    bool is_null(int col) const { return sqlite3_column_type(s_, col) == SQLITE_NULL; }
    bool is_text(int col) const { return sqlite3_column_type(s_, col) == SQLITE_TEXT; }
    double dbl(int col) const { return sqlite3_column_double(s_, col); }
    std::string text(int col) const {
      const auto* p = sqlite3_column_text(s_, col);
      return p ? std::string(reinterpret_cast<const char*>(p),
                             static_cast<std::size_t>(sqlite3_column_bytes(s_, col)))
               : std::string();
    }
    std::vector<double> doubles(int col) const {
      const void* p = sqlite3_column_blob(s_, col);
      const auto bytes = static_cast<std::size_t>(sqlite3_column_bytes(s_, col));
      std::vector<double> v(bytes / sizeof(double));
      if (p && !v.empty()) std::memcpy(v.data(), p, v.size() * sizeof(double));
      return v;
    }

   private:
    void check(int rc) {
      if (rc != SQLITE_OK) throw CatalogueError(std::string("sqlite bind: ") + sqlite3_errstr(rc));
    }
    SqliteConnection& c_;
    sqlite3_stmt* s_;
  };

  Stmt prepare(const std::string& sql) {
    auto it = cache_.find(sql);
    if (it == cache_.end()) {
      sqlite3_stmt* stmt = nullptr;
      if (sqlite3_prepare_v3(db_, sql.c_str(), -1, SQLITE_PREPARE_PERSISTENT, &stmt, nullptr) !=
          SQLITE_OK) {
        throw CatalogueError(std::string("sqlite prepare: ") + sqlite3_errmsg(db_) + " in " + sql);
      }
      it = cache_.emplace(sql, stmt).first;
    }
    return Stmt(*this, it->second);
  }

  int64_t changes() const { return sqlite3_changes64(db_); }
  int64_t last_insert_rowid() const { return sqlite3_last_insert_rowid(db_); }

  // BEGIN IMMEDIATE takes the write lock up front, so a read-modify-write never fails half
  // way with SQLITE_BUSY; the destructor rolls back unless commit() ran.
  class Transaction {
   public:
    explicit Transaction(SqliteConnection& c) : c_(c) { c_.exec("BEGIN IMMEDIATE"); }
    ~Transaction() {
      if (!done_) sqlite3_exec(c_.db_, "ROLLBACK", nullptr, nullptr, nullptr);
    }
    void commit() {
      c_.exec("COMMIT");
      done_ = true;
    }

   private:
    SqliteConnection& c_;
    bool done_ = false;
  };

 private:
  sqlite3* db_ = nullptr;
  std::unordered_map<std::string, sqlite3_stmt*> cache_;
};

}  // namespace detail

}  // namespace softshock::server
