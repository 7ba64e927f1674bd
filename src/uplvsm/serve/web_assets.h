// The viewer page's files (web/viewer/: HTML, JS, CSS), embedded into the binary at build time
// (cmake/embed_assets.cmake), so a fresh build and an installed binary serve the same page with no data files.
#pragma once
#include <string_view>
#include <vector>

namespace uplvsm::serve {

struct WebAsset {
  std::string_view path;  // "/index.html", "/viewer.js", ...
  std::string_view data;
};

const std::vector<WebAsset>& web_assets();

}  // namespace uplvsm::serve
