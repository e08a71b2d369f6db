// JPEG-LS decoder (ITU-T T.87 | ISO/IEC 14495-1, the LOCO-I algorithm).
//
// FLIR's .csq radiometric video stores each frame's raw 16-bit counts as a
// lossless JPEG-LS codestream inside an FFF record; this decoder returns them
// bit-exactly. It implements the baseline decoding process of T.87 Annex A:
// context modelling with the three quantized local gradients, the median edge
// detector prediction, bias correction, limited-length Golomb codes, run mode
// with run interruption samples, and near-lossless reconstruction (NEAR > 0),
// for 2-16 bit samples, any number of components, one scan per component
// (ILV = 0) or line interleaving (ILV = 1), default or preset (LSE) coding
// parameters.
//
// Not supported (a clear std::invalid_argument is thrown): sample
// interleaving (ILV = 2), mapping tables (LSE id 2/3 and non-zero Tm),
// restart intervals (DRI with Ri > 0), point transforms (Al > 0). FLIR
// cameras use none of them.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace qogi {

struct JpegLsImage {
  int width = 0;            // samples per line
  int height = 0;           // lines
  int components = 0;       // number of components (1 for FLIR raw frames)
  int bits_per_sample = 0;  // P of the frame header, 2..16
  int max_value = 0;        // MAXVAL used by the (last) scan
  int near = 0;             // NEAR of the (last) scan: 0 = lossless
  int interleave = 0;       // ILV of the (last) scan: 0 = none, 1 = line
  // Samples, planar: samples[(c * height + y) * width + x].
  std::vector<std::uint16_t> samples;
};

// Decodes one JPEG-LS codestream (SOI ... EOI). Throws std::invalid_argument
// naming the problem and its byte offset for malformed or unsupported input.
JpegLsImage DecodeJpegLs(const std::uint8_t* data, std::size_t size);

}  // namespace qogi
