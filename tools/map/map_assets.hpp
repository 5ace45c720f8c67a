// The live map's web assets (tools/map/web/*), compiled into locusd so the page needs nothing but
// locusd itself: no CDN, no files to install. The definitions are generated at build time by
// cmake/EmbedAssets.cmake from the files under tools/map/web.
#pragma once

#include <cstddef>
#include <string_view>

namespace locus::map {

struct Asset {
  std::string_view path;          ///< file name under web/, e.g. "index.html" (served at "/"), "map.js"
  std::string_view content_type;  ///< "text/html; charset=utf-8", ...
  std::string_view body;
};

extern const Asset kAssets[];
extern const std::size_t kAssetCount;

}  // namespace locus::map
