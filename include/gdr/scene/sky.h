// Daylight as Mitsuba 0.5/0.6's `sky`, `sun` and `sunsky` emitters define it,
// baked into a lat-long map for the `envmap` kind of Environment.
//
// The sky is the RGB version of Lukas Hosek and Alexander Wilkie, "An Analytic
// Model for Full Spectral Sky-Dome Radiance" (ACM TOG 31(4), 2012), divided by
// 106.856980 (the integral of the CIE 1931 y-bar matching function over
// wavelength, nm) so that its values are radiance in the units of the rest of
// the scene, as Mitsuba does; zero below the horizon. The sun is a disk of
// angular radius 0.2679 degrees times `sunRadiusScale` whose radiance times
// solid angle equals that of the true sun: its spectral radiance is that of
// A. J. Preetham, P. Shirley and B. Smits, "A Practical Analytic Model for
// Daylight" (SIGGRAPH 1999), the extraterrestrial solar spectrum attenuated by
// Rayleigh and aerosol (turbidity) extinction and ozone and water-vapour
// absorption along the relative optical air mass (the mixed-gas band at 760 nm
// lies outside the spectrum's 380-750 nm), and is taken to linear sRGB with
// the analytic CIE 1931 fit of C. Wyman, P.-P. Sloan and P. Shirley, "Simple
// Analytic Approximations to the CIE XYZ Color Matching Functions" (JCGT 2013).
//
// Directions are in the emitter's local frame, +y up, with the lat-long
// convention of gdr/scene/environment.h.
#pragma once

#include <array>

#include "gdr/core/image.h"
#include "gdr/core/math.h"

namespace gdr {

/// The Hosek-Wilkie RGB sky for one turbidity, ground albedo and solar elevation.
class HosekWilkieSky {
public:
    /// `turbidity` in [1, 10], `albedo` per channel in [0, 1], `solar_elevation`
    /// in radians above the horizon (clamped to [0, pi/2] as the model's fit
    /// covers). Throws ParameterError outside those ranges (elevation excepted).
    HosekWilkieSky(double turbidity, const Color& albedo, double solar_elevation);
    /// Radiance (scene units, W/(m^2 sr) after Mitsuba's normalisation) of
    /// channel `ch` at zenith angle `theta` (radians, < pi/2) and angle `gamma`
    /// (radians) from the sun.
    double radiance(int ch, double theta, double gamma) const;
    /// The nine interpolated parameters A B C D E F G I H of channel `ch`.
    const std::array<double, 9>& params(int ch) const { return config_[ch]; }
    /// The interpolated overall radiance L_M of channel `ch` (before normalisation).
    double overall(int ch) const { return overall_[ch]; }

private:
    std::array<std::array<double, 9>, 3> config_{};
    std::array<double, 3> overall_{};
};

/// Mitsuba's `sky` / `sun` / `sunsky` parameters (their defaults).
struct SkyParams {
    double turbidity = 3.0;          ///< Atmospheric turbidity, in [1, 10].
    Color albedo{0.15f};             ///< Ground albedo per channel, in [0, 1].
    Vec3 sun_dir{0.f, 1.f, 0.f};     ///< Unit local direction towards the sun (+y up).
    float sky_scale = 1.f;           ///< Factor on the sky's radiance (0: no sky).
    float sun_scale = 1.f;           ///< Factor on the sun's radiance (0: no sun).
    /// Factor on the sun's apparent radius (> 0 for a disk in the map; 0
    /// makes it a directional light of sun_irradiance(), left out of the map).
    float sun_radius_scale = 1.f;
    int resolution = 512;            ///< Map width in texels; the height is half of it.
    /// Mitsuba's `stretch`, in [1, 2]: a direction at zenith angle theta shows
    /// the model's sky at theta / stretch, so the sky reaches below the
    /// horizon (to stretch * 90 degrees), and the sun is drawn at stretch
    /// times its zenith angle.
    float stretch = 1.f;
    /// Mitsuba's `extend`: below the stretched horizon the sky keeps its
    /// horizon radiance, and the whole sky is faded by smoothstep(2 - 2
    /// theta / pi), reaching black at the nadir (a kludge for scenes that
    /// see below the horizon, as Mitsuba says).
    bool extend = false;
};

/// The unit local direction (+y up) at which the sun is drawn: the true sun
/// direction with its zenith angle multiplied by `stretch`.
Vec3 drawn_sun_direction(const SkyParams& p);

/// The irradiance (W/m^2, linear sRGB, scene units) of the sun as a
/// directional light, for sun_radius_scale 0: its radiance times the true
/// sun's solid angle, times sun_scale.
Color sun_irradiance(const SkyParams& p);

/// Angular radius of the sun seen from the earth, radians (0.5358 degrees diameter).
inline constexpr double kSunAngularRadius = 0.5358 * 0.5 * 3.14159265358979323846 / 180.0;

/// The sun's radiance (linear sRGB, scene units) at solar zenith angle `theta`
/// (radians) for `turbidity`; black once the sun is more than 3.885 degrees
/// below the horizon, where the air-mass formula ends.
Color sun_radiance(double theta, double turbidity);

/// Bakes sky (texel centres, as Mitsuba rasterises it) and sun disk (unless
/// sun_radius_scale is 0) into a resolution x resolution/2 RGB lat-long map
/// of local radiance.
/// Throws ParameterError on parameters out of range.
Image bake_sky(const SkyParams& p);

/// Unit local direction (+y up) of the sun at a date, time and place, by the
/// algorithm of M. Blanco-Muriel, D. C. Alarcon-Padilla, T. Lopez-Moratalla
/// and M. Lara-Coira, "Computing the solar vector" (Solar Energy 70(5), 2001),
/// which Mitsuba uses; azimuth measured from local -z towards +x. `hour` etc.
/// are local time in zone `timezone` (hours east of UTC); latitude and
/// longitude in degrees (north, east positive).
Vec3 sun_direction_at(int year, int month, int day, double hour, double minute, double second,
                      double latitude, double longitude, double timezone);

}  // namespace gdr
