#include "server/http/http_listener.hpp"

#include <httplib.h>

#include <condition_variable>
#include <deque>
#include <mutex>
#include <stdexcept>

#include "server/log.hpp"
#include "server/metrics/daemon_metrics.hpp"

namespace softshock::server {

namespace {

using Clock = std::chrono::steady_clock;

// The request being served on this thread: its route (for metrics) and when it started. A
// connection is served by one pool thread from its first request to its last.
thread_local std::string tl_route;
thread_local Clock::time_point tl_start{};

constexpr const char* kUnmatched = "unmatched";

// A fixed pool of threads over a bounded queue: enqueue() waits while the queue is full, so the
// accept loop stops accepting and new connections wait in the kernel's backlog.
class BoundedPool final : public httplib::TaskQueue {
 public:
  BoundedPool(int threads, std::size_t max_pending) : max_pending_(max_pending) {
    for (int i = 0; i < threads; ++i) threads_.emplace_back([this] { work(); });
  }
  ~BoundedPool() override { shutdown(); }

  void enqueue(std::function<void()> fn) override {
    std::unique_lock lock(mutex_);
    space_.wait(lock, [&] { return jobs_.size() < max_pending_ || stopping_; });
    jobs_.push_back(std::move(fn));  // after a stop too: the job closes its socket
    ready_.notify_one();
  }

  void shutdown() override {
    {
      std::lock_guard lock(mutex_);
      if (stopping_ && threads_.empty()) return;
      stopping_ = true;
    }
    ready_.notify_all();
    space_.notify_all();
    for (auto& t : threads_) t.join();
    threads_.clear();
  }

 private:
  void work() {
    for (;;) {
      std::function<void()> fn;
      {
        std::unique_lock lock(mutex_);
        ready_.wait(lock, [&] { return !jobs_.empty() || stopping_; });
        if (jobs_.empty()) return;  // stopping, and nothing left to close
        fn = std::move(jobs_.front());
        jobs_.pop_front();
        space_.notify_one();
      }
      fn();
    }
  }

  const std::size_t max_pending_;
  std::mutex mutex_;
  std::condition_variable ready_, space_;
  std::deque<std::function<void()>> jobs_;
  std::vector<std::thread> threads_;
  bool stopping_ = false;
};

const char* status_name(int status) {
  switch (status) {
    case 400:
      return "INVALID_ARGUMENT";
    case 401:
      return "UNAUTHENTICATED";
    case 403:
      return "PERMISSION_DENIED";
    case 404:
      return "NOT_FOUND";
    case 405:
      return "METHOD_NOT_ALLOWED";
    case 413:
      return "REQUEST_TOO_LARGE";
    case 414:
      return "URI_TOO_LONG";
    default:
      return status >= 500 ? "INTERNAL" : "HTTP_ERROR";
  }
}

}  // namespace

std::string json_quote(const std::string& s) {
  std::string out = "\"";
  for (unsigned char c : s) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += static_cast<char>(c);
    } else if (c < 0x20) {
      static const char* hex = "0123456789abcdef";
      out += "\\u00";
      out += hex[c >> 4];
      out += hex[c & 15];
    } else {
      out += static_cast<char>(c);
    }
  }
  return out + "\"";
}

void split_http_address(const std::string& address, std::string* host, int* port) {
  std::string h, p;
  if (!address.empty() && address[0] == '[') {
    const auto close = address.find(']');
    if (close == std::string::npos || close + 1 >= address.size() || address[close + 1] != ':') {
      throw std::invalid_argument("expects [v6-address]:port, not '" + address + "'");
    }
    h = address.substr(1, close - 1);
    p = address.substr(close + 2);
  } else {
    const auto colon = address.rfind(':');
    if (colon == std::string::npos || address.find(':') != colon) {
      throw std::invalid_argument("expects host:port (an IPv6 address in brackets), not '" +
                                  address + "'");
    }
    h = address.substr(0, colon);
    p = address.substr(colon + 1);
  }
  if (h.empty()) throw std::invalid_argument("expects a host before the port in '" + address + "'");
  int n = -1;
  if (!p.empty() && p.size() <= 5 && p.find_first_not_of("0123456789") == std::string::npos) {
    n = std::stoi(p);
  }
  if (n < 0 || n > 65535) {
    throw std::invalid_argument("expects a port in 0..65535 in '" + address + "'");
  }
  *host = h;
  *port = n;
}

std::string error_json(const std::string& code, const std::string& message) {
  return "{\"error\":{\"code\":" + json_quote(code) + ",\"message\":" + json_quote(message) + "}}";
}

void set_error(httplib::Response& res, int status, const std::string& code,
               const std::string& message) {
  res.status = status;
  res.set_header("Cache-Control", "no-store");
  res.set_content(error_json(code, message), "application/json");
}

HttpListener::HttpListener(HttpListenerOptions options, DaemonMetrics* metrics)
    : options_(std::move(options)), metrics_(metrics) {
  if (options_.tls_cert_file.empty() != options_.tls_key_file.empty()) {
    throw std::invalid_argument("TLS needs both a certificate and a key");
  }
  if (options_.tls_cert_file.empty()) {
    server_ = std::make_unique<httplib::Server>();
  } else {
    auto tls = std::make_unique<httplib::SSLServer>(options_.tls_cert_file.c_str(),
                                                    options_.tls_key_file.c_str());
    if (!tls->is_valid()) {
      throw std::runtime_error("cannot use the TLS certificate " + options_.tls_cert_file +
                               " and key " + options_.tls_key_file + " for " + options_.name);
    }
    server_ = std::move(tls);
  }
  httplib::Server& s = *server_;
  const int threads = std::max(1, options_.threads);
  const std::size_t pending = std::max<std::size_t>(1, options_.max_pending);
  s.new_task_queue = [threads, pending] { return new BoundedPool(threads, pending); };
  // SO_REUSEADDR only: the library's default adds SO_REUSEPORT, which would let a second daemon
  // bind the same port and silently take part of its connections (the gRPC port refuses it too).
  s.set_socket_options([](socket_t sock) {
    int yes = 1;
    ::setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
  });
  s.set_read_timeout(options_.io_timeout);
  s.set_write_timeout(options_.io_timeout);
  s.set_keep_alive_timeout(options_.keep_alive.count());
  s.set_keep_alive_max_count(100);
  s.set_payload_max_length(options_.max_request_bytes);
  httplib::Headers headers = {{"X-Content-Type-Options", "nosniff"},
                              {"Referrer-Policy", "no-referrer"},
                              {"X-Frame-Options", "DENY"}};
  for (const auto& [k, v] : options_.headers) headers.emplace(k, v);
  s.set_default_headers(headers);
  s.set_pre_routing_handler([](const httplib::Request&, httplib::Response&) {
    tl_route = kUnmatched;
    tl_start = Clock::now();
    return httplib::Server::HandlerResponse::Unhandled;
  });
  s.set_error_handler([](const httplib::Request&, httplib::Response& res) {
    if (!res.body.empty()) return;
    set_error(res, res.status, status_name(res.status),
              res.status == 404 ? "no such page" : "the request was refused");
  });
  s.set_exception_handler([name = options_.name](const httplib::Request& req,
                                                 httplib::Response& res, std::exception_ptr ep) {
    static LogRateLimit limit(20, 1);
    std::string what = "unknown exception";
    try {
      if (ep) std::rethrow_exception(ep);
    } catch (const std::exception& e) {
      what = e.what();
    } catch (...) {
    }
    log_limited(limit, LogLevel::kError,
                "http " + name + " " + log_field(req.method, 10) + " " + log_field(tl_route, 80) +
                    ": " + log_field(what, 300));
    set_error(res, 500, "INTERNAL", what);
  });
  s.set_logger([this](const httplib::Request&, const httplib::Response& res) {
    const double seconds = tl_start == Clock::time_point{}
                               ? 0.0
                               : std::chrono::duration<double>(Clock::now() - tl_start).count();
    if (metrics_ != nullptr) {
      metrics_->http_request(options_.name, tl_route.empty() ? kUnmatched : tl_route, res.status,
                             seconds);
    }
    tl_route.clear();
    tl_start = Clock::time_point{};
  });
}

HttpListener::~HttpListener() {
  stop();
}

HttpListener::Handler HttpListener::timed(const std::string& route, Handler handler) {
  return
      [route, handler = std::move(handler)](const httplib::Request& req, httplib::Response& res) {
        tl_route = route;
        handler(req, res);
      };
}

void HttpListener::get(const std::string& route, const std::string& pattern, Handler handler) {
  server_->Get(pattern, timed(route, std::move(handler)));
}

void HttpListener::post(const std::string& route, const std::string& pattern, Handler handler) {
  server_->Post(pattern, timed(route, std::move(handler)));
}

int HttpListener::start() {
  std::string host;
  int port = 0;
  try {
    split_http_address(options_.address, &host, &port);
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(options_.name + " listen address: " + e.what());
  }
  int bound = -1;
  if (port == 0) {
    bound = server_->bind_to_any_port(host);
  } else if (server_->bind_to_port(host, port)) {
    bound = port;
  }
  if (bound <= 0) {
    throw std::runtime_error("cannot listen on " + options_.address + " (" + options_.name + ")");
  }
  port_ = bound;
  thread_ = std::thread([this] { server_->listen_after_bind(); });
  return port_;
}

void HttpListener::stop() {
  if (!thread_.joinable()) return;
  server_->stop();
  thread_.join();
}

}  // namespace softshock::server
