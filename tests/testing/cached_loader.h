#pragma once
// An image loader that renders (or reads) each file once: the solver reads an image again for
// its background passes, and in the simulator tests every read is a render.

#include <map>
#include <memory>
#include <mutex>
#include <opencv2/core.hpp>
#include <string>

#include "processing/solver/pipeline.h"

namespace msmcal::testing {

// Thread-safe (the solver loads from several threads); each call returns its own copy.
inline solver::ImageLoader CachedLoader(solver::ImageLoader inner) {
  struct Cache {
    std::mutex mu;
    std::map<std::string, cv::Mat> images;
  };
  auto cache = std::make_shared<Cache>();
  return [cache, inner = std::move(inner)](const std::string& file) -> cv::Mat {
    {
      std::lock_guard<std::mutex> lock(cache->mu);
      if (auto it = cache->images.find(file); it != cache->images.end()) return it->second.clone();
    }
    cv::Mat img = inner(file);
    std::lock_guard<std::mutex> lock(cache->mu);
    cache->images.emplace(file, img);
    return img.clone();
  };
}

}  // namespace msmcal::testing
