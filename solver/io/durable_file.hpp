// Durable small-file operations: after a crash a file written with these is either absent or
// whole (write + fsync, then rename, then fsync of the folder). Used by result files and the
// daemon's uploaded meshes. Each throws std::runtime_error naming the path and the errno.
#pragma once

#include <filesystem>
#include <string>

namespace softshock {

void fsync_path(const std::filesystem::path& p, bool directory);
// Writes p's data to the disk now (fdatasync), so that a later fsync_path has little left to wait
// for: a writer thread calls it as it goes. Best effort: an error here is ignored (the final fsync
// reports it).
void write_back(const std::filesystem::path& p) noexcept;
// Creates or truncates p, writes content, fsyncs and closes.
void write_file_synced(const std::filesystem::path& p, const std::string& content);
// rename(2): atomic within a filesystem.
void rename_file(const std::filesystem::path& from, const std::filesystem::path& to);

}  // namespace softshock
