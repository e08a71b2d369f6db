// Helpers for the spectra tests: the HITRAN files the package ships, and scratch files.
#pragma once

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

namespace qogi {
namespace testing_util {

// The gzip-compressed HITRAN subsets shipped in the Python package
// (python/qogi/data/hitran, provenance in its MANIFEST.json).
inline std::string HitranDir() { return std::string(QOGI_SOURCE_DIR) + "/python/qogi/data/hitran"; }

// A fresh scratch directory, removed when the object goes out of scope.
class ScratchDir {
 public:
  ScratchDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    path_ = std::filesystem::temp_directory_path() /
            (std::string("qogi_spectra_") + info->test_suite_name() + "_" + info->name() + "_" +
             std::to_string(std::rand()));
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~ScratchDir() { std::filesystem::remove_all(path_); }
  std::string File(const std::string& name) const { return (path_ / name).string(); }
  std::string Write(const std::string& name, const std::string& text) const {
    const std::string p = File(name);
    std::ofstream(p, std::ios::binary) << text;
    return p;
  }

 private:
  std::filesystem::path path_;
};

}  // namespace testing_util
}  // namespace qogi
