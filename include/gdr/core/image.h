// Float images and named frame buffers: the currency between integrators,
// reconstructors and file I/O. Layout is row-major, channels interleaved,
// row 0 at the top of the picture, (x, y) = (column, row).
#pragma once

#include <cstddef>
#include <map>
#include <string>
#include <vector>

#include "gdr/core/error.h"
#include "gdr/core/math.h"

namespace gdr {

/// A width x height image with 1..4 float channels (values in the layer's own
/// units: radiance for colour layers, metres for depth, unitless for normals).
class Image {
public:
    Image() = default;
    /// An image of the given size filled with `fill`.
    Image(int width, int height, int channels, float fill = 0.f)
        : w_(width), h_(height), c_(channels), data_(size_t(width) * height * channels, fill) {
        if (width < 0 || height < 0 || channels < 1 || channels > 4)
            throw ParameterError("Image: bad size " + std::to_string(width) + "x" + std::to_string(height) + "x" +
                                 std::to_string(channels));
    }

    int width() const { return w_; }            ///< Columns.
    int height() const { return h_; }           ///< Rows.
    int channels() const { return c_; }         ///< Channels per pixel.
    size_t pixel_count() const { return size_t(w_) * h_; }  ///< width * height.
    bool empty() const { return data_.empty(); }             ///< No pixels.

    /// Channel `ch` of pixel (x, y).
    float& at(int x, int y, int ch = 0) { return data_[(size_t(y) * w_ + x) * c_ + ch]; }
    /// Channel `ch` of pixel (x, y).
    float at(int x, int y, int ch = 0) const { return data_[(size_t(y) * w_ + x) * c_ + ch]; }

    /// Pixel (x, y) as RGB (a 1-channel image is broadcast to grey).
    Color rgb(int x, int y) const {
        const float* p = &data_[(size_t(y) * w_ + x) * c_];
        return c_ >= 3 ? Color(p[0], p[1], p[2]) : Color(p[0]);
    }
    /// Stores RGB at (x, y); needs at least 3 channels.
    void set_rgb(int x, int y, const Color& v) {
        float* p = &data_[(size_t(y) * w_ + x) * c_];
        p[0] = v.r, p[1] = v.g, p[2] = v.b;
    }

    float* data() { return data_.data(); }                  ///< Raw interleaved storage.
    const float* data() const { return data_.data(); }      ///< Raw interleaved storage.
    std::vector<float>& values() { return data_; }          ///< Raw interleaved storage.
    const std::vector<float>& values() const { return data_; }  ///< Raw interleaved storage.

    /// True if both images have the same width, height and channel count.
    bool same_shape(const Image& o) const { return w_ == o.w_ && h_ == o.h_ && c_ == o.c_; }

private:
    int w_ = 0, h_ = 0, c_ = 0;
    std::vector<float> data_;
};

/// Throws InputError naming `what` and the first pixel holding NaN or Inf.
void require_finite(const Image& img, const std::string& what);

/// Named image layers of one render (e.g. "color", "dx", "albedo"); all
/// layers share one resolution. Iteration order is the insertion order.
class FrameBuffer {
public:
    FrameBuffer() = default;
    /// An empty buffer of the given resolution.
    FrameBuffer(int width, int height) : w_(width), h_(height) {}

    int width() const { return w_; }    ///< Columns of every layer.
    int height() const { return h_; }   ///< Rows of every layer.

    /// Adds (or replaces) a zero-filled layer and returns it.
    Image& add(const std::string& name, int channels) { return set(name, Image(w_, h_, channels)); }
    /// Adds (or replaces) a layer; its size must match the buffer.
    Image& set(const std::string& name, Image img);
    /// True if a layer of that name exists.
    bool has(const std::string& name) const { return index_.count(name) != 0; }
    /// The named layer; throws ParameterError listing the layers if absent.
    Image& get(const std::string& name);
    /// The named layer; throws ParameterError listing the layers if absent.
    const Image& get(const std::string& name) const;
    /// Layer names in insertion order.
    const std::vector<std::string>& names() const { return order_; }
    /// Removes a layer if present.
    void remove(const std::string& name);

    /// Free-form metadata (render settings) written to and read from file headers.
    std::map<std::string, std::string>& metadata() { return meta_; }
    /// Free-form metadata (render settings) written to and read from file headers.
    const std::map<std::string, std::string>& metadata() const { return meta_; }

private:
    int w_ = 0, h_ = 0;
    std::vector<std::string> order_;
    std::map<std::string, Image> index_;
    std::map<std::string, std::string> meta_;
};

}  // namespace gdr
