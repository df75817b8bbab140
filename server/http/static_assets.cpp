#include "server/http/static_assets.hpp"

#include <httplib.h>

namespace softshock::server::http {

const StaticAsset* find_static_asset(std::string_view name) {
  for (const auto& a : static_assets()) {
    if (name == a.name) return &a;
  }
  return nullptr;
}

void answer_asset(const httplib::Request& req, httplib::Response& res, const StaticAsset& asset) {
  res.set_header("ETag", asset.etag);
  res.set_header("Cache-Control", "no-cache");
  if (req.get_header_value("If-None-Match") == asset.etag) {
    res.status = 304;
    return;
  }
  res.status = 200;
  res.set_content(reinterpret_cast<const char*>(asset.data), asset.size, asset.content_type);
}

}  // namespace softshock::server::http
