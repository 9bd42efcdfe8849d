// Pinhole perspective camera with the ordinary look-at convention:
// image right = normalize(cross(forward, up)), image up = cross(right, forward).
#pragma once

#include "gdr/core/math.h"

namespace gdr {

/// A ray: origin (scene units), unit direction, and the parametric interval [tmin, tmax].
struct Ray {
    Vec3 o{0.f}, d{0.f, 0.f, 1.f};
    float tmin = 0.f, tmax = kInf;
};

/// Camera parameters as they appear in scene files.
struct CameraDesc {
    Vec3 position{0.f, 0.f, 0.f};  ///< Eye point (scene units).
    Vec3 target{0.f, 0.f, -1.f};   ///< Point looked at.
    Vec3 up{0.f, 1.f, 0.f};        ///< Approximate up vector.
    float fov_deg = 45.f;          ///< Full field of view in degrees along fov_axis.
    char fov_axis = 'y';           ///< 'x' (horizontal) or 'y' (vertical).
    int width = 512, height = 512; ///< Resolution in pixels.
};

/// Pinhole camera; film coordinates are continuous pixel units, (0,0) at the
/// top-left corner of the top-left pixel, x right, y down.
class Camera {
public:
    Camera() : Camera(CameraDesc{}) {}
    /// Validates the description (throws ParameterError on a degenerate one).
    explicit Camera(const CameraDesc& d);

    /// The primary ray through film point `film` (pixel units).
    Ray generate_ray(const Vec2& film) const {
        // The image plane at distance 1 is affine in the film point: no division per ray.
        return Ray{desc_.position, glm::normalize(corner_ + film.x * per_pixel_x_ + film.y * per_pixel_y_)};
    }
    /// Film point (pixel units) where the direction from the eye through p lands; false if behind the camera.
    bool project(const Vec3& p, Vec2& film) const;
    /// Importance We of the pinhole for unit world direction w leaving the
    /// eye, normalised over the whole film (Veach 1997, section 8.1.1):
    /// 1 / (A cos^4 theta) with A film_area_at_unit_distance() and theta
    /// the angle to the viewing direction, so that its integral of
    /// We cos theta over the directions through the film is 1 (units 1/sr);
    /// 0 outside the film. Sets `film` to the raster point w passes through.
    float importance(const Vec3& w, Vec2& film) const;
    /// Solid-angle density (1/sr) of the primary-ray direction w when the
    /// film point is uniform over the whole film, 1 / (A cos^3 theta); 0
    /// outside the film. Light tracing's MIS compares it with light-subpath densities.
    float direction_pdf(const Vec3& w) const;
    /// Area of the image plane at distance 1 (for importance / pdf conversions), in scene units^2.
    float film_area_at_unit_distance() const { return 4.f * tan_half_x_ * tan_half_y_; }

    int width() const { return desc_.width; }    ///< Pixels across.
    int height() const { return desc_.height; }  ///< Pixels down.
    const CameraDesc& desc() const { return desc_; }  ///< The description it was built from.
    const Vec3& forward() const { return forward_; }   ///< Unit viewing direction.
    const Vec3& position() const { return desc_.position; }  ///< The eye point (scene units).

private:
    CameraDesc desc_;
    Vec3 forward_, right_, up_;
    float tan_half_x_ = 1.f, tan_half_y_ = 1.f;
    // Image-plane point (distance 1) of film (0,0), and its change per pixel in x and y.
    Vec3 corner_, per_pixel_x_, per_pixel_y_;
};

}  // namespace gdr
