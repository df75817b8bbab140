// The PNG export of the CLI: matplotlib lives in Python, so the CLI writes the numbers to a
// temporary folder and runs the plotting helper `python3 -m softshock_client.plots` on them.
#pragma once

#include <string>
#include <vector>

namespace softshock::cli {

// Runs `python3 -m softshock_client.plots ARGS...` (interpreter $SOFTSHOCK_PYTHON, package from
// $SOFTSHOCK_PYTHONPATH, the installed copy, or this source tree). Throws CliError on failure.
void run_python_plot(const std::vector<std::string>& args);

// A private temporary folder, removed with its content on destruction.
class TempDir {
 public:
  TempDir();
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

// Writes text to a file (for the helper's JSON input). Throws CliError.
void write_text_file(const std::string& path, const std::string& text);

}  // namespace softshock::cli
