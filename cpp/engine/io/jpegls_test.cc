// The JPEG-LS decoder against CharLS: codestreams written by CharLS and the
// checksums of CharLS's decoding of them (tests/data/jpegls, made by
// make_reference.py there), plus malformed and unsupported input.
#include "engine/io/jpegls.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <fstream>
#include <iterator>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace qogi {
namespace {

const std::string kDir = std::string(QOGI_SOURCE_DIR) + "/tests/data/jpegls/";

std::vector<std::uint8_t> ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot open " + path);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

std::uint64_t Fnv1a64(const std::vector<std::uint16_t>& samples) {
  std::uint64_t h = 0xCBF29CE484222325ull;
  for (std::uint16_t v : samples)
    for (std::uint8_t byte :
         {static_cast<std::uint8_t>(v & 0xFF), static_cast<std::uint8_t>(v >> 8)}) {
      h ^= byte;
      h *= 0x100000001B3ull;
    }
  return h;
}

std::string DecodeError(const std::vector<std::uint8_t>& code) {
  try {
    DecodeJpegLs(code.data(), code.size());
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

TEST(JpegLs, MatchesCharLsOnEveryReferenceCase) {
  std::ifstream manifest(kDir + "manifest.txt");
  ASSERT_TRUE(manifest) << "missing " << kDir << "manifest.txt";
  std::string line;
  int cases = 0;
  while (std::getline(manifest, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream row(line);
    std::string name, hash;
    int c, h, w, bits, near, ilv;
    row >> name >> c >> h >> w >> bits >> near >> ilv >> hash;
    const auto code = ReadFile(kDir + name + ".jls");
    const JpegLsImage img = DecodeJpegLs(code.data(), code.size());
    EXPECT_EQ(img.components, c) << name;
    EXPECT_EQ(img.height, h) << name;
    EXPECT_EQ(img.width, w) << name;
    EXPECT_EQ(img.bits_per_sample, bits) << name;
    EXPECT_EQ(img.near, near) << name;
    EXPECT_EQ(img.interleave, ilv) << name;
    EXPECT_EQ(Fnv1a64(img.samples), std::stoull(hash, nullptr, 16)) << name;
    ++cases;
  }
  EXPECT_GE(cases, 15);
}

TEST(JpegLs, RejectsStreamsThatAreNotJpegLs) {
  EXPECT_NE(DecodeError({0x00, 0x01, 0x02, 0x03}).find("no SOI"), std::string::npos);
  // A baseline JPEG header (SOF0).
  const std::vector<std::uint8_t> jpeg = {0xFF, 0xD8, 0xFF, 0xC0, 0x00, 0x0B, 8, 0,
                                          8,    0,    8,    1,    1,    0x11, 0};
  EXPECT_NE(DecodeError(jpeg).find("not JPEG-LS"), std::string::npos);
}

TEST(JpegLs, TruncatedScanDataIsAnError) {
  auto code = ReadFile(kDir + "gray16_sensor.jls");
  code.resize(code.size() / 2);
  EXPECT_NE(DecodeError(code).find("ended before the image was complete"), std::string::npos);
}

TEST(JpegLs, SampleInterleavingIsReportedAsUnsupported) {
  auto code = ReadFile(kDir + "rgb8_ilv1.jls");
  // The SOS header: FF DA Ls Ns (Ci Tmi)*3 NEAR ILV Al; set ILV to 2.
  std::size_t sos = 0;
  while (!(code[sos] == 0xFF && code[sos + 1] == 0xDA)) ++sos;
  code[sos + 4 + 1 + 6 + 1] = 2;
  EXPECT_NE(DecodeError(code).find("ILV = 2"), std::string::npos);
}

TEST(JpegLs, MissingEndOfImageIsAnError) {
  auto code = ReadFile(kDir + "gray8_smooth.jls");
  code.resize(code.size() - 2);  // drop EOI
  EXPECT_FALSE(DecodeError(code).empty());
}

}  // namespace
}  // namespace qogi
