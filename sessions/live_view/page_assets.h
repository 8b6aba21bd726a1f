#pragma once
// The live view's static page (sessions/live_view/page/), embedded at build time by
// embed_page.cmake: served by LiveServer from memory, so the page works from any build folder
// and offline.

#include <cstddef>

namespace msmcal::live_view {

struct PageAsset {
  const char* path;          // "/index.html", "/live.js", "/live.css"
  const char* content_type;  // "text/html; charset=utf-8", ...
  const unsigned char* data;
  size_t size;
};

extern const PageAsset kPageAssets[];
extern const size_t kPageAssetCount;

}  // namespace msmcal::live_view
