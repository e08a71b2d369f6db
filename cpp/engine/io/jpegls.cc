// JPEG-LS decoding process, ITU-T T.87 Annex A (see jpegls.h for the scope).
// Section numbers in comments are T.87's.
#include "engine/io/jpegls.h"

#include <algorithm>
#include <array>
#include <cstdlib>
#include <stdexcept>
#include <string>
#include <utility>

namespace qogi {
namespace {

[[noreturn]] void Fail(const std::string& what, std::size_t offset) {
  throw std::invalid_argument("JPEG-LS: " + what + " (at byte " + std::to_string(offset) + ")");
}

// Run-length order table J (A.7.1.2).
constexpr std::array<int, 32> kJ = {0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2,  2,  3,  3,  3,  3,
                                    4, 4, 5, 5, 6, 6, 7, 7, 8, 9, 10, 11, 12, 13, 14, 15};

// Reads the entropy-coded segment of a scan, MSB first, removing the stuffed
// zero bit that follows every 0xFF data byte (A.1).
class BitReader {
 public:
  BitReader(const std::uint8_t* begin, const std::uint8_t* end, std::size_t base)
      : begin_(begin), p_(begin), end_(end), base_(base) {}

  int ReadBit() {
    if (bits_ < 1) Fill(1);
    const int bit = static_cast<int>(cache_ >> 63);
    cache_ <<= 1;
    --bits_;
    return bit;
  }

  // n in [1, 16].
  int ReadBits(int n) {
    if (bits_ < n) Fill(n);
    const int v = static_cast<int>(cache_ >> (64 - n));
    cache_ <<= n;
    bits_ -= n;
    return v;
  }

  // Number of 0 bits before the next 1 bit (which is consumed); more than
  // `max_zeros` zeros is corrupt data.
  int ReadUnary(int max_zeros) {
    int q = 0;
    for (;;) {
      if (bits_ == 0) Fill(1);
      if (cache_ == 0) {  // only zero bits buffered
        q += bits_;
        cache_ = 0;
        bits_ = 0;
        if (q > max_zeros) Fail("corrupt Golomb code (unary part too long)", Offset());
        continue;
      }
      const int lz = __builtin_clzll(cache_);
      q += lz;
      if (q > max_zeros) Fail("corrupt Golomb code (unary part too long)", Offset());
      cache_ <<= lz;
      cache_ <<= 1;
      bits_ -= lz + 1;
      return q;
    }
  }

  // Byte offset (in the whole codestream) of the next unread byte.
  std::size_t Offset() const { return base_ + static_cast<std::size_t>(p_ - begin_); }

 private:
  // Buffers at least `need` bits or fails.
  void Fill(int need) {
    while (bits_ <= 48 && p_ < end_) {
      const std::uint8_t b = *p_++;
      cache_ |= static_cast<std::uint64_t>(b) << (56 - bits_);
      bits_ += 8;
      if (b == 0xFF && p_ < end_) {
        // The byte after a data 0xFF carries a stuffed 0 bit and 7 data bits.
        const std::uint8_t n = *p_++;
        cache_ |= static_cast<std::uint64_t>(n & 0x7F) << (57 - bits_);
        bits_ += 7;
      }
    }
    if (bits_ < need) Fail("scan data ended before the image was complete", Offset());
  }

  const std::uint8_t* begin_;
  const std::uint8_t* p_;
  const std::uint8_t* end_;
  std::size_t base_;
  std::uint64_t cache_ = 0;  // buffered bits, MSB-aligned
  int bits_ = 0;             // number of buffered bits
};

struct CodingParameters {
  int maxval = 0, near = 0, t1 = 0, t2 = 0, t3 = 0, reset = 0;
  int range = 0, qbpp = 0, limit = 0;
};

int BitsFor(int n) {  // ceil(log2(n)) for n >= 1
  int b = 0;
  while ((1 << b) < n) ++b;
  return b;
}

// T.87 C.2.4.1.1: default thresholds; `Clamp` is the standard's CLAMP,
// which returns j (not MAXVAL) when i > MAXVAL.
int StdClamp(int i, int j, int maxval) { return (i > maxval || i < j) ? j : i; }

CodingParameters MakeParameters(int bits, int preset_maxval, int preset_t1, int preset_t2,
                                int preset_t3, int preset_reset, int near, std::size_t offset) {
  CodingParameters p;
  p.maxval = preset_maxval > 0 ? preset_maxval : (1 << bits) - 1;
  p.near = near;
  if (near < 0 || near > std::min(255, p.maxval / 2))
    Fail("NEAR " + std::to_string(near) + " out of range [0, min(255, MAXVAL/2)]", offset);
  int t1, t2, t3;
  if (p.maxval >= 128) {
    const int factor = (std::min(p.maxval, 4095) + 128) / 256;
    t1 = StdClamp(factor * (3 - 2) + 2 + 3 * near, near + 1, p.maxval);
    t2 = StdClamp(factor * (7 - 3) + 3 + 5 * near, t1, p.maxval);
    t3 = StdClamp(factor * (21 - 4) + 4 + 7 * near, t2, p.maxval);
  } else {
    const int factor = 256 / (p.maxval + 1);
    t1 = StdClamp(std::max(2, 3 / factor + 3 * near), near + 1, p.maxval);
    t2 = StdClamp(std::max(3, 7 / factor + 5 * near), t1, p.maxval);
    t3 = StdClamp(std::max(4, 21 / factor + 7 * near), t2, p.maxval);
  }
  p.t1 = preset_t1 > 0 ? preset_t1 : t1;
  p.t2 = preset_t2 > 0 ? preset_t2 : t2;
  p.t3 = preset_t3 > 0 ? preset_t3 : t3;
  p.reset = preset_reset > 0 ? preset_reset : 64;
  if (!(near + 1 <= p.t1 && p.t1 <= p.t2 && p.t2 <= p.t3 && p.t3 <= p.maxval))
    Fail("thresholds T1=" + std::to_string(p.t1) + " T2=" + std::to_string(p.t2) +
             " T3=" + std::to_string(p.t3) + " not ordered NEAR+1 <= T1 <= T2 <= T3 <= MAXVAL",
         offset);
  if (p.reset < 3 || p.reset > std::max(255, p.maxval))
    Fail("RESET " + std::to_string(p.reset) + " out of range", offset);
  p.range = (p.maxval + 2 * near) / (2 * near + 1) + 1;
  p.qbpp = BitsFor(p.range);
  const int bpp = std::max(2, BitsFor(p.maxval + 1));
  p.limit = 2 * (bpp + std::max(8, bpp));
  return p;
}

// Context state and the line decoder of one scan (A.2-A.7).
class ScanDecoder {
 public:
  ScanDecoder(const CodingParameters& p, BitReader& bits) : p_(p), bits_(bits) {
    const int a0 = std::max(2, (p.range + 32) / 64);
    a_.fill(a0);
    b_.fill(0);
    c_.fill(0);
    n_.fill(1);
    run_a_ = {a0, a0};
    run_n_ = {1, 1};
    run_nn_ = {0, 0};
    // Gradient quantization table over [-maxval, maxval] (A.3.3).
    quant_.resize(2 * static_cast<std::size_t>(p.maxval) + 1);
    for (int d = -p.maxval; d <= p.maxval; ++d) quant_[d + p.maxval] = Quantize(d);
  }

  // Decodes one line into cur[0..width), with prev the line above. Both
  // point one element into buffers of width + 2 samples whose [-1] and
  // [width] entries the caller has set (A.2.1 edge rules).
  void DecodeLine(const int* prev, int* cur, int width, int& run_index) {
    int x = 0;
    while (x < width) {
      const int ra = cur[x - 1], rb = prev[x], rc = prev[x - 1], rd = prev[x + 1];
      int q1 = quant_[rd - rb + p_.maxval];
      int q2 = quant_[rb - rc + p_.maxval];
      int q3 = quant_[rc - ra + p_.maxval];
      if (q1 == 0 && q2 == 0 && q3 == 0) {
        x = DecodeRun(prev, cur, x, width, run_index);
        continue;
      }
      cur[x] = DecodeRegular(ra, rb, rc, q1, q2, q3);
      ++x;
    }
  }

 private:
  int Quantize(int d) const {
    if (d <= -p_.t3) return -4;
    if (d <= -p_.t2) return -3;
    if (d <= -p_.t1) return -2;
    if (d < -p_.near) return -1;
    if (d <= p_.near) return 0;
    if (d < p_.t1) return 1;
    if (d < p_.t2) return 2;
    if (d < p_.t3) return 3;
    return 4;
  }

  // Limited-length Golomb code (A.5.3).
  int DecodeValue(int k, int limit) {
    const int q = bits_.ReadUnary(limit - p_.qbpp - 1);
    if (q < limit - p_.qbpp - 1) return (q << k) | (k > 0 ? bits_.ReadBits(k) : 0);
    return bits_.ReadBits(p_.qbpp) + 1;
  }

  // Modulo reduction and clamping of a reconstructed sample (A.4.2, A.5.4).
  int Reconstruct(int px, int err_q) const {
    const int step = 2 * p_.near + 1;
    int rx = px + err_q * step;
    if (rx < -p_.near)
      rx += p_.range * step;
    else if (rx > p_.maxval + p_.near)
      rx -= p_.range * step;
    return std::clamp(rx, 0, p_.maxval);
  }

  int DecodeRegular(int ra, int rb, int rc, int q1, int q2, int q3) {
    int sign = 1;
    if (q1 < 0 || (q1 == 0 && (q2 < 0 || (q2 == 0 && q3 < 0)))) {
      sign = -1;
      q1 = -q1;
      q2 = -q2;
      q3 = -q3;
    }
    const int q = (q1 + 4) * 81 + (q2 + 4) * 9 + (q3 + 4);
    // Median edge detector (A.4.1) and bias correction (A.4.2).
    int px;
    if (rc >= std::max(ra, rb))
      px = std::min(ra, rb);
    else if (rc <= std::min(ra, rb))
      px = std::max(ra, rb);
    else
      px = ra + rb - rc;
    px = std::clamp(px + sign * c_[q], 0, p_.maxval);
    int k = 0;
    while ((n_[q] << k) < a_[q]) ++k;
    const int merr = DecodeValue(k, p_.limit);
    int err;  // A.5.2 inverse error mapping
    if (p_.near == 0 && k == 0 && 2 * b_[q] <= -n_[q])
      err = (merr & 1) ? (merr - 1) / 2 : -(merr / 2) - 1;
    else
      err = (merr & 1) ? -((merr + 1) >> 1) : (merr >> 1);
    UpdateRegular(q, err);
    return Reconstruct(px, sign * err);
  }

  // A.6.1 variables update and A.6.2 bias computation.
  void UpdateRegular(int q, int err) {
    b_[q] += err * (2 * p_.near + 1);
    a_[q] += std::abs(err);
    if (n_[q] == p_.reset) {
      a_[q] >>= 1;
      b_[q] = b_[q] >= 0 ? b_[q] >> 1 : -((1 - b_[q]) >> 1);
      n_[q] >>= 1;
    }
    ++n_[q];
    if (b_[q] <= -n_[q]) {
      b_[q] += n_[q];
      if (c_[q] > -128) --c_[q];
      if (b_[q] <= -n_[q]) b_[q] = -n_[q] + 1;
    } else if (b_[q] > 0) {
      b_[q] -= n_[q];
      if (c_[q] < 127) ++c_[q];
      if (b_[q] > 0) b_[q] = 0;
    }
  }

  // Run mode (A.7): returns the position after the run (and after its run
  // interruption sample, if any).
  int DecodeRun(const int* prev, int* cur, int x, int width, int& run_index) {
    const int ra = cur[x - 1];
    const int remaining = width - x;
    int count = 0;
    bool end_of_line = false;
    while (bits_.ReadBit()) {
      const int rm = 1 << kJ[run_index];
      const int n = std::min(rm, remaining - count);
      count += n;
      if (n == rm && run_index < 31) ++run_index;
      if (count == remaining) {
        end_of_line = true;
        break;
      }
    }
    if (!end_of_line) {
      if (kJ[run_index] > 0) count += bits_.ReadBits(kJ[run_index]);
      if (count >= remaining) Fail("run length beyond the end of the line", bits_.Offset());
    }
    for (int i = 0; i < count; ++i) cur[x + i] = ra;
    x += count;
    if (end_of_line) return x;

    // Run interruption sample (A.7.2).
    const int rb = prev[x];
    const int ri = std::abs(ra - rb) <= p_.near ? 1 : 0;
    const int px = ri ? ra : rb;
    const int sign = (ri == 0 && ra > rb) ? -1 : 1;
    const int temp = ri ? run_a_[ri] + (run_n_[ri] >> 1) : run_a_[ri];
    int k = 0;
    while ((run_n_[ri] << k) < temp) ++k;
    const int em = DecodeValue(k, p_.limit - kJ[run_index] - 1);
    const int t = em + ri;
    const int map = t & 1;
    const int abs_err = (t + map) >> 1;
    const bool negative = (k != 0 || 2 * run_nn_[ri] >= run_n_[ri]) == (map == 1);
    const int err = negative ? -abs_err : abs_err;
    if (err < 0) ++run_nn_[ri];
    run_a_[ri] += (em + 1 - ri) >> 1;
    if (run_n_[ri] == p_.reset) {
      run_a_[ri] >>= 1;
      run_n_[ri] >>= 1;
      run_nn_[ri] >>= 1;
    }
    ++run_n_[ri];
    cur[x] = Reconstruct(px, sign * err);
    if (run_index > 0) --run_index;
    return x + 1;
  }

  const CodingParameters& p_;
  BitReader& bits_;
  std::array<int, 729> a_, b_, c_, n_;  // indexed by (Q1+4)*81+(Q2+4)*9+(Q3+4)
  std::array<int, 2> run_a_, run_n_, run_nn_;  // run interruption contexts
  std::vector<signed char> quant_;
};

class Parser {
 public:
  Parser(const std::uint8_t* data, std::size_t size) : d_(data), size_(size) {}

  JpegLsImage Run() {
    if (size_ < 4 || d_[0] != 0xFF || d_[1] != 0xD8)
      Fail("not a JPEG-LS codestream (no SOI marker 0xFFD8 at the start)", 0);
    pos_ = 2;
    bool frame = false, any_scan = false;
    for (;;) {
      const int marker = NextMarker();
      const std::size_t at = pos_ - 2;
      if (marker == 0xD9) {  // EOI
        if (!frame || !any_scan) Fail("EOI before any frame and scan", at);
        for (int c = 0; c < img_.components; ++c)
          if (!decoded_[c]) Fail("component " + std::to_string(c) + " has no scan", at);
        return std::move(img_);
      }
      const std::size_t len = Read16();
      if (len < 2 || pos_ - 2 + len > size_) Fail("segment length out of bounds", at);
      const std::size_t end = pos_ - 2 + len;
      if (marker == 0xF7) {  // SOF55: JPEG-LS frame
        if (frame) Fail("more than one frame header", at);
        ReadFrame(end);
        frame = true;
      } else if (marker == 0xF8) {  // LSE
        ReadPreset(end);
      } else if (marker == 0xDA) {  // SOS
        if (!frame) Fail("scan before the frame header", at);
        ReadScanAndDecode(end);
        any_scan = true;
        continue;  // pos_ is now after the entropy-coded data
      } else if (marker == 0xDD) {  // DRI
        if (len >= 4 && Peek16(pos_) != 0) Fail("restart intervals are not supported", at);
      } else if ((marker >= 0xE0 && marker <= 0xEF) || marker == 0xFE) {
        // APPn, COM: skipped.
      } else if (marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 &&
                 marker != 0xCC) {
        Fail("this is a JPEG (T.81) stream, not JPEG-LS (frame marker 0xFF" + Hex(marker) + ")",
             at);
      } else {
        Fail("unexpected marker 0xFF" + Hex(marker), at);
      }
      pos_ = end;
    }
  }

 private:
  static std::string Hex(int v) {
    static const char* digits = "0123456789ABCDEF";
    return std::string{digits[(v >> 4) & 15], digits[v & 15]};
  }
  int Peek16(std::size_t at) const { return (d_[at] << 8) | d_[at + 1]; }
  int Read8() {
    if (pos_ >= size_) Fail("unexpected end of data", pos_);
    return d_[pos_++];
  }
  int Read16() {
    if (pos_ + 2 > size_) Fail("unexpected end of data", pos_);
    const int v = Peek16(pos_);
    pos_ += 2;
    return v;
  }
  int NextMarker() {
    if (pos_ + 2 > size_) Fail("unexpected end of data (no EOI marker)", pos_);
    if (d_[pos_] != 0xFF) Fail("expected a marker", pos_);
    while (pos_ < size_ && d_[pos_] == 0xFF) ++pos_;  // fill bytes
    if (pos_ >= size_) Fail("unexpected end of data", pos_);
    return d_[pos_++];
  }

  void ReadFrame(std::size_t end) {
    const std::size_t at = pos_;
    const int p = Read8();
    const int y = Read16(), x = Read16(), nf = Read8();
    if (p < 2 || p > 16) Fail("sample precision P=" + std::to_string(p) + " not in [2, 16]", at);
    if (nf < 1 || nf > 255) Fail("number of components must be >= 1", at);
    if (pos_ + 3 * static_cast<std::size_t>(nf) > end) Fail("frame header too short", at);
    ids_.clear();
    for (int c = 0; c < nf; ++c) {
      ids_.push_back(Read8());
      Read8();  // sampling factors
      if (Read8() != 0) Fail("Tq must be 0 in a JPEG-LS frame header", pos_ - 1);
    }
    img_.bits_per_sample = p;
    img_.components = nf;
    img_.height = y > 0 ? y : oversize_height_;
    img_.width = x > 0 ? x : oversize_width_;
    if (img_.height <= 0 || img_.width <= 0)
      Fail("image dimensions are zero (no LSE oversize-dimension segment)", at);
    img_.samples.assign(static_cast<std::size_t>(nf) * img_.height * img_.width, 0);
    decoded_.assign(nf, false);
  }

  void ReadPreset(std::size_t end) {
    const std::size_t at = pos_;
    const int id = Read8();
    if (id == 1) {
      preset_maxval_ = Read16();
      preset_t1_ = Read16();
      preset_t2_ = Read16();
      preset_t3_ = Read16();
      preset_reset_ = Read16();
    } else if (id == 4) {
      const int wxy = Read8();
      if (wxy < 2 || wxy > 4) Fail("oversize-dimension width Wxy must be 2..4", at);
      long long yy = 0, xx = 0;
      for (int i = 0; i < wxy; ++i) yy = (yy << 8) | Read8();
      for (int i = 0; i < wxy; ++i) xx = (xx << 8) | Read8();
      if (yy > (1 << 30) || xx > (1 << 30)) Fail("image too large", at);
      oversize_height_ = static_cast<int>(yy);
      oversize_width_ = static_cast<int>(xx);
      if (img_.components > 0) {  // frame already read with zero dimensions
        if (img_.height == 0) img_.height = oversize_height_;
        if (img_.width == 0) img_.width = oversize_width_;
      }
    } else {
      Fail("LSE segment id " + std::to_string(id) + " (mapping tables) is not supported", at);
    }
    (void)end;
  }

  void ReadScanAndDecode(std::size_t header_end) {
    const std::size_t at = pos_;
    const int ns = Read8();
    if (ns < 1 || ns > img_.components) Fail("bad number of scan components", at);
    std::vector<int> comps;
    for (int i = 0; i < ns; ++i) {
      const int id = Read8();
      const int tm = Read8();
      if (tm != 0) Fail("mapping tables (Tm != 0) are not supported", pos_ - 1);
      const auto it = std::find(ids_.begin(), ids_.end(), id);
      if (it == ids_.end()) Fail("scan names unknown component " + std::to_string(id), at);
      const int c = static_cast<int>(it - ids_.begin());
      if (decoded_[c]) Fail("component " + std::to_string(id) + " coded twice", at);
      comps.push_back(c);
    }
    const int near = Read8();
    const int ilv = Read8();
    const int al = Read8() & 0x0F;
    if (al != 0) Fail("point transform (Al > 0) is not supported", pos_ - 1);
    if (ilv == 2) Fail("sample interleaving (ILV = 2) is not supported", pos_ - 2);
    if (ilv > 2) Fail("invalid interleave mode ILV = " + std::to_string(ilv), pos_ - 2);
    if (ilv == 0 && ns != 1) Fail("ILV = 0 requires one component per scan", at);
    pos_ = header_end;

    const CodingParameters params = MakeParameters(img_.bits_per_sample, preset_maxval_, preset_t1_,
                                                   preset_t2_, preset_t3_, preset_reset_, near, at);
    if (params.maxval >= (1 << img_.bits_per_sample))
      Fail("MAXVAL " + std::to_string(params.maxval) +
               " does not fit in P=" + std::to_string(img_.bits_per_sample) + " bits",
           at);
    img_.max_value = params.maxval;
    img_.near = near;
    img_.interleave = ilv;

    // The entropy-coded segment ends at the first 0xFF followed by a byte
    // with its high bit set (a stuffed 0xFF is followed by a byte < 0x80).
    std::size_t data_end = pos_;
    while (data_end + 1 < size_ && !(d_[data_end] == 0xFF && d_[data_end + 1] >= 0x80)) ++data_end;
    if (data_end + 1 >= size_) data_end = size_;

    BitReader bits(d_ + pos_, d_ + data_end, pos_);
    ScanDecoder decoder(params, bits);
    const int w = img_.width, h = img_.height;
    std::vector<std::vector<int>> prev(ns, std::vector<int>(w + 2, 0));
    std::vector<std::vector<int>> cur(ns, std::vector<int>(w + 2, 0));
    std::vector<int> run_index(ns, 0);
    for (int y = 0; y < h; ++y) {
      for (int i = 0; i < ns; ++i) {
        int* pv = prev[i].data() + 1;
        int* cv = cur[i].data() + 1;
        pv[w] = pv[w - 1];  // Rd of the last sample
        cv[-1] = pv[0];     // Ra of the first sample; pv[-1] holds Rc
        decoder.DecodeLine(pv, cv, w, run_index[i]);
        std::uint16_t* out = img_.samples.data() + (static_cast<std::size_t>(comps[i]) * h + y) * w;
        for (int x = 0; x < w; ++x) out[x] = static_cast<std::uint16_t>(cv[x]);
        std::swap(prev[i], cur[i]);
      }
    }
    for (int c : comps) decoded_[c] = true;
    pos_ = data_end;
  }

  const std::uint8_t* d_;
  std::size_t size_;
  std::size_t pos_ = 0;
  JpegLsImage img_;
  std::vector<int> ids_;
  std::vector<bool> decoded_;
  int preset_maxval_ = 0, preset_t1_ = 0, preset_t2_ = 0, preset_t3_ = 0, preset_reset_ = 0;
  int oversize_height_ = 0, oversize_width_ = 0;
};

}  // namespace

JpegLsImage DecodeJpegLs(const std::uint8_t* data, std::size_t size) {
  if (data == nullptr && size > 0) throw std::invalid_argument("JPEG-LS: null data");
  return Parser(data, size).Run();
}

}  // namespace qogi
