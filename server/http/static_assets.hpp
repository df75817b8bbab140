// The dashboard's pages, scripts and styles (server/http/web/), compiled into softshockd at build
// time (embed_assets.cmake), so the daemon serves them with no file to install or fetch.
#pragma once

#include <cstddef>
#include <string_view>
#include <vector>

namespace httplib {
struct Request;
struct Response;
}  // namespace httplib

namespace softshock::server::http {

struct StaticAsset {
  const char* name;  // "index.html", "app.js"
  const char* content_type;
  const unsigned char* data;
  std::size_t size;
  const char* etag;  // quoted, from the content's SHA-256
};

const std::vector<StaticAsset>& static_assets();
const StaticAsset* find_static_asset(std::string_view name);

// Answers `asset` (304 when the request's If-None-Match is its ETag); revalidated on every use
// (Cache-Control: no-cache), so a new daemon's pages replace the old at once.
void answer_asset(const httplib::Request& req, httplib::Response& res, const StaticAsset& asset);

}  // namespace softshock::server::http
