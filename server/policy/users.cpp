#include "server/policy/users.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <stdexcept>

#include "server/store/spec_hash.hpp"

namespace softshock::server {

namespace {

constexpr const char* kWhitespace = " \t\r\n\v\f";

std::string trim(std::string_view s) {
  const auto first = s.find_first_not_of(kWhitespace);
  if (first == std::string_view::npos) return {};
  return std::string(s.substr(first, s.find_last_not_of(kWhitespace) - first + 1));
}

// The bytes of a file that holds secrets, checked on the file actually read (fstat), so a swap
// between check and read cannot help: a regular file, not readable or writable by other users,
// at most max_bytes. `what` names it in errors ("token file", "users file").
std::string read_secret_file(const std::string& path, const char* what, std::size_t max_bytes) {
  const std::string name = std::string(what) + " " + path;
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw std::runtime_error("cannot read " + name);
  struct stat st {};
  const bool stat_ok = ::fstat(fd, &st) == 0;
  std::string bytes;
  char buf[4096];
  for (ssize_t n; (n = ::read(fd, buf, sizeof buf)) != 0;) {
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 || bytes.size() > max_bytes) {
      ::close(fd);
      throw std::runtime_error("cannot read " + name + " (or it is over " +
                               std::to_string(max_bytes / 1024) + " KiB)");
    }
    bytes.append(buf, static_cast<std::size_t>(n));
  }
  ::close(fd);
  if (!stat_ok || !S_ISREG(st.st_mode)) throw std::runtime_error(name + " is not a regular file");
  if ((st.st_mode & (S_IROTH | S_IWOTH)) != 0) {
    char mode[8];
    std::snprintf(mode, sizeof mode, "%04o", static_cast<unsigned>(st.st_mode & 07777));
    throw std::runtime_error(name + " is accessible to other users (mode " + mode +
                             "); chmod o-rwx it (0600, or 0640 with the daemon's group)");
  }
  return bytes;
}

std::string short_token_rule(std::size_t got) {
  return "holds " + std::to_string(got) + " bytes; a token needs at least " +
         std::to_string(kMinTokenBytes) + " (e.g. head -c 32 /dev/urandom | base64)";
}

}  // namespace

const char* to_string(Role role) {
  return role == Role::kAdmin ? "admin" : "user";
}

bool valid_user_name(std::string_view name) {
  if (name.empty() || name.size() > kMaxUserNameBytes || name[0] == '.' || name[0] == '-') {
    return false;
  }
  return std::all_of(name.begin(), name.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' ||
           c == '_' || c == '-';
  });
}

bool constant_time_equal(std::string_view a, std::string_view b) {
  // Runs over the longer length; a length difference only shows in the result.
  const std::size_t n = std::max(a.size(), b.size());
  unsigned char diff = a.size() == b.size() ? 0 : 1;
  for (std::size_t i = 0; i < n; ++i) {
    const unsigned char ca = i < a.size() ? static_cast<unsigned char>(a[i]) : 0;
    const unsigned char cb = i < b.size() ? static_cast<unsigned char>(b[i]) : 0;
    diff |= static_cast<unsigned char>(ca ^ cb);
  }
  return diff == 0;
}

std::string read_token_file(const std::string& path) {
  const std::string token = trim(read_secret_file(path, "token file", kMaxTokenFileBytes));
  if (token.empty()) throw std::runtime_error("token file " + path + " is empty");
  if (token.size() < kMinTokenBytes) {
    throw std::runtime_error("token file " + path + " " + short_token_rule(token.size()));
  }
  return token;
}

std::vector<UserEntry> read_users_file(const std::string& path) {
  const std::string text = read_secret_file(path, "users file", kMaxUsersFileBytes);
  std::vector<UserEntry> out;
  UserTable check;  // the table's own rules (names, lengths, duplicates), per line
  std::size_t start = 0;
  for (int line_no = 1; start <= text.size(); ++line_no) {
    std::size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    const std::string line = trim(std::string_view(text).substr(start, end - start));
    start = end + 1;
    if (line.empty() || line[0] == '#') continue;
    const std::string where = "users file " + path + ":" + std::to_string(line_no) + ": ";
    const auto c1 = line.find(':');
    const auto c2 = c1 == std::string::npos ? c1 : line.find(':', c1 + 1);
    if (c1 == std::string::npos ||
        (c2 != std::string::npos && line.find(':', c2 + 1) != std::string::npos)) {
      throw std::runtime_error(where + "expected user:token or user:token:role");
    }
    UserEntry entry;
    entry.user = line.substr(0, c1);
    entry.token = c2 == std::string::npos ? line.substr(c1 + 1) : line.substr(c1 + 1, c2 - c1 - 1);
    if (c2 != std::string::npos) {
      const std::string role = line.substr(c2 + 1);
      if (role == "admin") {
        entry.role = Role::kAdmin;
      } else if (role != "user") {
        throw std::runtime_error(where + "role '" + role + "' is neither user nor admin");
      }
    }
    if (entry.token.find_first_of(kWhitespace) != std::string::npos) {
      throw std::runtime_error(where + "the token of " + entry.user + " contains whitespace");
    }
    try {
      check.add(entry);
    } catch (const std::invalid_argument& e) {
      throw std::runtime_error(where + e.what());
    }
    out.push_back(std::move(entry));
  }
  return out;
}

void UserTable::add(UserEntry entry) {
  if (!valid_user_name(entry.user)) {
    throw std::invalid_argument("user name '" + entry.user.substr(0, kMaxUserNameBytes + 1) +
                                "' must be 1 to 64 of A-Z a-z 0-9 . _ -, not starting with . or -");
  }
  if (entry.token.size() < kMinTokenBytes) {
    throw std::invalid_argument("the token of " + entry.user + " " +
                                short_token_rule(entry.token.size()));
  }
  const std::string digest = sha256_hex(entry.token);
  for (const auto& u : users_) {
    if (u.caller.user == entry.user) {
      throw std::invalid_argument("user " + entry.user + " is given twice");
    }
    if (u.digest == digest) {
      throw std::invalid_argument("user " + entry.user + " has the same token as " + u.caller.user +
                                  "; every user needs a token of their own");
    }
  }
  users_.push_back({Caller{std::move(entry.user), entry.role}, digest});
}

std::optional<Caller> UserTable::find(std::string_view token) const {
  const std::string digest = sha256_hex(token);
  const Stored* match = nullptr;
  for (const auto& u : users_) {
    // No early exit: every entry costs the same whether or not an earlier one matched.
    const bool equal = constant_time_equal(digest, u.digest);
    if (equal) match = &u;
  }
  if (match == nullptr) return std::nullopt;
  return match->caller;
}

std::vector<Caller> UserTable::callers() const {
  std::vector<Caller> out;
  for (const auto& u : users_) out.push_back(u.caller);
  return out;
}

UserTable load_users(const std::string& token_file, const std::string& token_user,
                     const std::string& users_file) {
  UserTable table;
  try {
    if (!token_file.empty()) {
      table.add({token_user.empty() ? kDefaultUser : token_user, read_token_file(token_file),
                 Role::kAdmin});
    }
    if (!users_file.empty()) {
      for (auto& entry : read_users_file(users_file)) table.add(std::move(entry));
    }
  } catch (const std::invalid_argument& e) {
    // A users-file line that clashes with the token file's user or token.
    throw std::runtime_error(std::string(e.what()) + " (token file " + token_file +
                             " and users file " + users_file + ")");
  }
  return table;
}

}  // namespace softshock::server
