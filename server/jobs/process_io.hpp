// Running a command without a shell, and small files written durably: what the slurm
// executor needs from the operating system (kept apart so the executor reads as Slurm logic).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace softshock::server {

struct CommandResult {
  int status = -1;  // exit status; -1 = could not run or killed
  std::string out, err;
};

// Runs argv[0] (found on PATH) without a shell (arguments never need quoting), stdin from
// /dev/null, and collects its output. The child gets default signal handling back: the daemon
// blocks SIGTERM/SIGINT in every thread and ignores SIGPIPE, and exec would pass both on.
CommandResult run_command(const std::vector<std::string>& argv);

// Writes and fsyncs the file and its folder. Throws std::runtime_error.
void write_text(const std::filesystem::path& path, const std::string& text);

// The file's content; empty when it cannot be read.
std::string read_text(const std::filesystem::path& path);

}  // namespace softshock::server
