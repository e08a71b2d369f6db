// Bindings of engine/io: the JPEG-LS decoder.
#include "common.h"

#include <cstring>

#include "engine/io/jpegls.h"

namespace qogi {

void BindIo(py::module_& m) {
  m.def(
      "decode_jpegls",
      [](py::buffer data) {
        const py::buffer_info info = data.request();
        if (info.ndim != 1 || info.itemsize != 1 || info.strides[0] != 1)
          throw std::invalid_argument(
              "decode_jpegls: data must be a contiguous bytes-like object");
        const auto* bytes = static_cast<const std::uint8_t*>(info.ptr);
        const std::size_t size = static_cast<std::size_t>(info.size);
        JpegLsImage img;
        {
          py::gil_scoped_release release;
          img = DecodeJpegLs(bytes, size);
        }
        const std::vector<py::ssize_t> shape = {img.components, img.height, img.width};
        py::array out;
        if (img.bits_per_sample <= 8) {
          py::array_t<std::uint8_t> a(shape);
          std::uint8_t* dst = a.mutable_data();
          for (std::size_t i = 0; i < img.samples.size(); ++i)
            dst[i] = static_cast<std::uint8_t>(img.samples[i]);
          out = a;
        } else {
          py::array_t<std::uint16_t> a(shape);
          std::memcpy(a.mutable_data(), img.samples.data(),
                      img.samples.size() * sizeof(std::uint16_t));
          out = a;
        }
        py::dict meta;
        meta["width"] = img.width;
        meta["height"] = img.height;
        meta["components"] = img.components;
        meta["bits_per_sample"] = img.bits_per_sample;
        meta["max_value"] = img.max_value;
        meta["near"] = img.near;
        meta["interleave"] = img.interleave;
        return py::make_tuple(out, meta);
      },
      py::arg("data"),
      "Decode a JPEG-LS (ITU-T T.87) codestream. Returns (samples, info): samples "
      "shaped (components, height, width), uint8 for <= 8-bit samples else uint16; "
      "info a dict (width, height, components, bits_per_sample, max_value, near, "
      "interleave). Raises ValueError for malformed or unsupported streams.");
}

}  // namespace qogi
