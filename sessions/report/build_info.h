#pragma once
// What this binary was built from, captured by cmake/build_info.cmake at every build (the
// generated build_info.cc is rewritten only when the text changes).

namespace msmcal::report {

const char* MsmcalVersion();  // the CMake project version ("0.1.0")
// `git describe --always --dirty --abbrev=12` of the source tree at build time ("c0e8a1f5a2b3",
// "c0e8a1f5a2b3-dirty"); "unknown" when built outside a git checkout.
const char* GitCommit();
const char* BuildType();  // CMAKE_BUILD_TYPE ("RelWithDebInfo")

}  // namespace msmcal::report
