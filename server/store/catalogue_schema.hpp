// The catalogue's schema (server/store/ only): tables, indexes and their migrations.
#pragma once

#include <string>

#include "server/store/sqlite_connection.hpp"

namespace softshock::server::detail {

// Brings the catalogue at `path` (open on `c`) to the newest schema, in one transaction;
// returns that version. Throws CatalogueError for a catalogue newer than this softshockd.
int migrate_catalogue(SqliteConnection& c, const std::string& path);

// The newest schema version, and the SQL that brings version `from` to from + 1 (tests build
// catalogues of older versions with it, exactly as older softshockds left them).
int catalogue_schema_version();
const char* catalogue_migration(int from);

}  // namespace softshock::server::detail
