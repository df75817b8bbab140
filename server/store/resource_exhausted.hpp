// Out of room: a quota, the disk reserve, the disk itself (ENOSPC) or a bound on concurrent work.
// The RPC wrapper (transport/rpc_guard.hpp) answers RESOURCE_EXHAUSTED with the message, which
// says which bound and how to get below it.
#pragma once

#include <stdexcept>

namespace softshock::server {

class ResourceExhausted : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace softshock::server
