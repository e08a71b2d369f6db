// Bindings of engine/io: the JPEG-LS decoder.
#include "common.h"

#include <cstdint>

#include "engine/io/jpegls.h"

namespace qogi {

void BindIo(py::module_& m) {
  m.def(
      "decode_jpegls",
      [](py::buffer data) {
        const py::buffer_info info = data.request();
        if (info.ndim != 1 || info.itemsize != 1 || info.strides[0] != 1)
          throw std::invalid_argument("decode_jpegls: data must be a contiguous bytes-like object");
        const auto* bytes = static_cast<const std::uint8_t*>(info.ptr);
        const std::size_t size = static_cast<std::size_t>(info.size);
        JpegLsImage img;
        {
          py::gil_scoped_release release;
          img = DecodeJpegLs(bytes, size);
        }
        const std::vector<py::ssize_t> shape = {img.components, img.height, img.width};
        py::array out = img.bits_per_sample <= 8
                            ? py::array(ToArray<std::uint8_t>(img.samples, shape))
                            : py::array(ToArray(img.samples, shape));
        using J = JpegLsImage;
        const py::dict meta =
            ToDict(img, Field("width", &J::width), Field("height", &J::height),
                   Field("components", &J::components),
                   Field("bits_per_sample", &J::bits_per_sample), Field("max_value", &J::max_value),
                   Field("near", &J::near), Field("interleave", &J::interleave));
        return py::make_tuple(out, meta);
      },
      py::arg("data"),
      "Decode a JPEG-LS (ITU-T T.87) codestream. Returns (samples, info): samples "
      "shaped (components, height, width), uint8 for <= 8-bit samples else uint16; "
      "info a dict (width, height, components, bits_per_sample, max_value, near, "
      "interleave). Raises ValueError for malformed or unsupported streams.");
}

}  // namespace qogi
