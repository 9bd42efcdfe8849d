// A tiny 8-bit RGB raster for benchmark figures: rectangles, lines, text in
// stb_easy_font's built-in bitmap font, log-log line plots, and PNG output.
// It exists so the benchmark can draw its own plots with no Python or
// plotting library on the machine.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "gdr/core/image.h"
#include "gdr/eval/equal_time.h"

namespace gdr::eval {

/// An sRGB-encoded 8-bit colour.
struct Rgb8 {
    uint8_t r = 0, g = 0, b = 0;
};

/// A width x height 8-bit RGB picture, row 0 at the top.
class Canvas {
public:
    Canvas() = default;
    /// A canvas filled with `bg`; throws ParameterError on a negative size.
    Canvas(int width, int height, Rgb8 bg = {255, 255, 255});

    int width() const { return w_; }   ///< Pixels across.
    int height() const { return h_; }  ///< Pixels down.

    /// Sets one pixel; outside the canvas it is ignored (clipping).
    void set(int x, int y, Rgb8 c);
    /// The pixel at (x, y) (must be inside).
    Rgb8 get(int x, int y) const;
    /// Fills the pixels [x0, x1) x [y0, y1), clipped.
    void fill_rect(int x0, int y0, int x1, int y1, Rgb8 c);
    /// A line of `thickness` pixels between two points (pixel units); dash > 0
    /// draws dashes and gaps of that many pixels.
    void line(double x0, double y0, double x1, double y1, Rgb8 c, int thickness = 1, int dash = 0);
    /// Text with its top-left corner at (x, y), each font pixel drawn as scale x scale.
    void text(int x, int y, const std::string& s, Rgb8 c, int scale = 1);
    /// Width in pixels that text(s, scale) covers.
    static int text_width(const std::string& s, int scale = 1);
    /// Height in pixels of one text line at `scale`.
    static int text_height(int scale = 1);
    /// Copies `src` with its top-left corner at (x, y), clipped.
    void blit(const Canvas& src, int x, int y);
    /// Writes a PNG; throws RuntimeFailure naming the file on error.
    void write_png(const std::string& path) const;

private:
    int w_ = 0, h_ = 0;
    std::vector<uint8_t> px_;
};

/// A linear-radiance image as an sRGB canvas: scaled by `scale`, clamped to [0,1], sRGB-encoded.
Canvas tonemap(const Image& linear, float scale);

/// The scale that maps the `percentile` (0..1) luminance of `img` to 1 (for tonemap); 1 if that is 0.
float auto_exposure(const Image& img, double percentile = 0.97);

/// One curve of a plot.
struct Series {
    std::string label;               ///< Legend text.
    Rgb8 color;                      ///< Line colour.
    std::vector<CurvePoint> points;  ///< (time, error) points, drawn in time order.
    bool dashed = false;             ///< Dashed line (for secondary curves).
};

/// A log-log line plot with axes, ticks, labels, grid and a legend.
struct LogLogPlot {
    std::string title;                   ///< Text above the plot.
    std::string xlabel, ylabel;          ///< Axis labels.
    std::vector<Series> series;          ///< Curves, legend in this order.
    double hline = 0.0;                  ///< If > 0, a thin grey horizontal line at this y (e.g. a target error).
    std::string hline_label;             ///< Text next to the horizontal line.
    std::vector<double> xticks;          ///< If set, x ticks at these values (e.g. the time budgets) instead of 1-2-5 steps.
};

/// Draws the plot on a new width x height canvas; non-positive points are skipped.
Canvas draw_loglog(const LogLogPlot& plot, int width = 640, int height = 440);

}  // namespace gdr::eval
