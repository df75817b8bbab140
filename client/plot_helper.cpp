#include "client/plot_helper.hpp"

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "client/cli_common.hpp"

#ifndef SOFTSHOCK_PYTHON_EXE
#define SOFTSHOCK_PYTHON_EXE "/usr/bin/python3"
#endif
#ifndef SOFTSHOCK_CLIENT_PYTHON_DIR
#define SOFTSHOCK_CLIENT_PYTHON_DIR ""
#endif

extern char** environ;

namespace softshock::cli {

namespace {

std::string self_exe_dir() {
  std::error_code ec;
  auto p = std::filesystem::read_symlink("/proc/self/exe", ec);
  return ec ? std::string() : p.parent_path().string();
}

// Where the softshock_client package is: $SOFTSHOCK_PYTHONPATH, the installed copy next to
// the binary (PREFIX/share/softshock/python), else the source tree this binary was built from.
std::string client_python_path() {
  if (const char* env = std::getenv("SOFTSHOCK_PYTHONPATH"); env && *env) return env;
  std::string installed = self_exe_dir() + "/../share/softshock/python";
  if (std::filesystem::exists(installed + "/softshock_client/plots.py")) return installed;
  return SOFTSHOCK_CLIENT_PYTHON_DIR;
}

}  // namespace

// Runs the plotting helper (matplotlib lives in Python; an image encoder here would be a
// second, worse copy of it). Its stderr passes through so a missing package is visible.
void run_python_plot(const std::vector<std::string>& args) {
  const char* py_env = std::getenv("SOFTSHOCK_PYTHON");
  std::string python = py_env && *py_env ? py_env : SOFTSHOCK_PYTHON_EXE;
  std::string path = client_python_path();
  if (const char* old = std::getenv("PYTHONPATH"); old && *old) path += std::string(":") + old;
  std::vector<std::string> env_strings = {"PYTHONPATH=" + path, "MPLBACKEND=Agg"};
  for (char** e = environ; *e; ++e) {
    if (std::strncmp(*e, "PYTHONPATH=", 11) != 0 && std::strncmp(*e, "MPLBACKEND=", 11) != 0) {
      env_strings.emplace_back(*e);
    }
  }
  std::vector<std::string> argv_strings = {python, "-m", "softshock_client.plots"};
  argv_strings.insert(argv_strings.end(), args.begin(), args.end());
  std::vector<char*> argv, envp;
  for (auto& s : argv_strings) argv.push_back(s.data());
  argv.push_back(nullptr);
  for (auto& s : env_strings) envp.push_back(s.data());
  envp.push_back(nullptr);
  std::fflush(stdout);
  // The plot helper must not write to our stdout: JSON/scripted output stays clean.
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, STDERR_FILENO, STDOUT_FILENO);
  pid_t pid = 0;
  int rc = posix_spawn(&pid, python.c_str(), &actions, nullptr, argv.data(), envp.data());
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) {
    throw CliError(kExitFailure, "cannot run " + python + " for the PNG: " + std::strerror(rc));
  }
  int wstatus = 0;
  while (waitpid(pid, &wstatus, 0) < 0 && errno == EINTR) {
  }
  if (!WIFEXITED(wstatus) || WEXITSTATUS(wstatus) != 0) {
    throw CliError(kExitFailure, "the plotting helper (" + python +
                                     " -m softshock_client.plots) failed; PYTHONPATH=" + path);
  }
}

TempDir::TempDir() {
  const char* base = std::getenv("TMPDIR");
  std::string tmpl = std::string(base && *base ? base : "/tmp") + "/softshock-XXXXXX";
  if (mkdtemp(tmpl.data()) == nullptr) {
    throw CliError(kExitFailure,
                   "cannot make a temporary directory: " + std::string(std::strerror(errno)));
  }
  path_ = tmpl;
}

TempDir::~TempDir() {
  std::error_code ec;
  std::filesystem::remove_all(path_, ec);
}

void write_text_file(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << text;
  out.flush();
  if (!out) throw CliError(kExitFailure, path + ": " + std::strerror(errno));
}

}  // namespace softshock::cli
