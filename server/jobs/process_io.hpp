// Running a command without a shell, and small files written durably: what the slurm
// executor needs from the operating system (kept apart so the executor reads as Slurm logic).
#pragma once

#include <chrono>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace softshock::server {

struct CommandResult {
  int status = -1;       // exit status; -1 = could not run or killed
  int signal = 0;        // the signal that ended it, if one did
  bool stopped = false;  // killed because should_stop() said so
  std::string out, err;  // each capped at kMaxCommandOutput (the end is kept)
};

// A child that talks more than this (a crash dump, a chatty library) costs no more memory.
inline constexpr std::size_t kMaxCommandOutput = 256 * 1024;

// Runs argv[0] (found on PATH when it has no '/') without a shell (arguments never need
// quoting), stdin from /dev/null, and collects its output. The child gets default signal
// handling back: the daemon blocks SIGTERM/SIGINT in every thread and ignores SIGPIPE, and exec
// would pass both on. posix_spawn, not fork: forking the multi-threaded daemon would copy
// locks held by other threads into a child that never releases them.
//
// With should_stop, it is asked every poll_interval while the child runs; once it answers true
// the child is killed with SIGKILL (it may be deep in a library that never checks for
// anything) and reaped, and the result says stopped.
CommandResult run_command(const std::vector<std::string>& argv,
                          const std::function<bool()>& should_stop = {},
                          std::chrono::milliseconds poll_interval = std::chrono::milliseconds(20));

// Writes and fsyncs the file and its folder. Throws std::runtime_error.
void write_text(const std::filesystem::path& path, const std::string& text);

// The file's content; empty when it cannot be read.
std::string read_text(const std::filesystem::path& path);

}  // namespace softshock::server
