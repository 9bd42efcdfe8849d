#include "gdr/core/image.h"

#include <algorithm>
#include <cmath>

namespace gdr {

void require_finite(const Image& img, const std::string& what) {
    const auto& v = img.values();
    for (size_t i = 0; i < v.size(); ++i) {
        if (!std::isfinite(v[i])) {
            const size_t px = i / img.channels();
            const int x = int(px % img.width()), y = int(px / img.width());
            throw InputError(what + ": non-finite value (" + std::to_string(v[i]) + ") at pixel (" + std::to_string(x) +
                             ", " + std::to_string(y) + ") channel " + std::to_string(i % img.channels()));
        }
    }
}

Image& FrameBuffer::set(const std::string& name, Image img) {
    if (w_ == 0 && h_ == 0 && order_.empty()) w_ = img.width(), h_ = img.height();
    if (img.width() != w_ || img.height() != h_)
        throw ParameterError("layer '" + name + "' is " + std::to_string(img.width()) + "x" +
                             std::to_string(img.height()) + " but the frame buffer is " + std::to_string(w_) + "x" +
                             std::to_string(h_));
    if (!has(name)) order_.push_back(name);
    return index_[name] = std::move(img);
}

static std::string list_names(const std::vector<std::string>& names) {
    std::string s;
    for (const auto& n : names) s += (s.empty() ? "" : ", ") + n;
    return s.empty() ? "(none)" : s;
}

Image& FrameBuffer::get(const std::string& name) {
    auto it = index_.find(name);
    if (it == index_.end()) throw ParameterError("no layer '" + name + "' (layers: " + list_names(order_) + ")");
    return it->second;
}

const Image& FrameBuffer::get(const std::string& name) const {
    auto it = index_.find(name);
    if (it == index_.end()) throw ParameterError("no layer '" + name + "' (layers: " + list_names(order_) + ")");
    return it->second;
}

void FrameBuffer::remove(const std::string& name) {
    if (!has(name)) return;
    index_.erase(name);
    order_.erase(std::find(order_.begin(), order_.end(), name));
}

}  // namespace gdr
