// Who may call softshockd: users, their bearer tokens and roles. Read from the daemon's secret
// files -- `--token-file` (one token: one user, an admin, as before users existed) and
// `--users-file` (one `user:token[:role]` line per user) -- with the same rules for both: a
// regular file that other users may neither read nor write, tokens of at least 32 bytes. No gRPC
// here (the transport's processor asks the table; server/transport/auth.hpp).
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace softshock::server {

enum class Role { kUser, kAdmin };
const char* to_string(Role role);

// The identity a call runs as.
struct Caller {
  std::string user;
  Role role = Role::kUser;
  bool is_admin() const { return role == Role::kAdmin; }
};

// Owner of what existed before owners did (a data folder upgraded to catalogue schema 8, mesh
// records without an owner), the single --token-file user unless --token-user names another, and
// every caller of a daemon without authentication (who is then an admin: it is one user's
// daemon).
inline constexpr const char* kDefaultUser = "default";

// A guessable token is no protection: at least 32 bytes (e.g. 32 random bytes in base64).
inline constexpr std::size_t kMinTokenBytes = 32;
inline constexpr std::size_t kMaxTokenFileBytes = 64 * 1024;
inline constexpr std::size_t kMaxUsersFileBytes = 1 << 20;
inline constexpr std::size_t kMaxUserNameBytes = 64;

// User names: 1 to 64 of [A-Za-z0-9._-], not starting with '.' or '-' (they appear in logs, list
// filters and the CLI's columns).
bool valid_user_name(std::string_view name);

// Reads the daemon's token file; surrounding whitespace (a trailing newline) is trimmed. Throws
// std::runtime_error if it cannot be read, is not a regular file, is readable or writable by
// other users (mode o+r or o+w), or holds fewer than kMinTokenBytes after trimming.
std::string read_token_file(const std::string& path);

// Compares without an early exit, so timing does not reveal how much of a guess matched.
bool constant_time_equal(std::string_view a, std::string_view b);

struct UserEntry {
  std::string user, token;
  Role role = Role::kUser;
};

// Reads a users file: one `user:token[:role]` per line (role `user`, the default, or `admin`);
// blank lines and lines starting with '#' are skipped; whitespace around a line is ignored.
// Throws std::runtime_error naming the file and line (never the token) for a file that breaks
// the secret-file rules, a malformed line, a bad name or role, a short token, or a user or token
// given twice.
std::vector<UserEntry> read_users_file(const std::string& path);

// The users a daemon accepts. Empty = authentication disabled.
class UserTable {
 public:
  // Throws std::invalid_argument for a bad name, a short token, or a name or token already in
  // the table.
  void add(UserEntry entry);
  bool empty() const { return users_.empty(); }
  std::size_t size() const { return users_.size(); }
  // The user holding `token`. Every entry is compared, each in constant time over SHA-256
  // digests (so neither the position nor the length of a match shows in the timing).
  std::optional<Caller> find(std::string_view token) const;
  std::vector<Caller> callers() const;

 private:
  struct Stored {
    Caller caller;
    std::string digest;  // hex SHA-256 of the token
  };
  std::vector<Stored> users_;
};

// The table of a daemon's settings: the token file's token as `token_user` (an admin), then every
// line of the users file. Both empty = an empty table. Throws std::runtime_error.
UserTable load_users(const std::string& token_file, const std::string& token_user,
                     const std::string& users_file);

}  // namespace softshock::server
