// Typed exceptions thrown by library code. Only the CLI prints and exits.
#pragma once

#include <stdexcept>
#include <string>

namespace gdr {

/// Base of every gdr exception; what() is one complete, user-facing line.
class Error : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

/// Bad input data: a missing or malformed file, a NaN in a buffer, a degenerate mesh.
class InputError : public Error {
public:
    using Error::Error;
};

/// Bad parameter: unknown or ill-typed key, out-of-range value, unknown plugin name.
class ParameterError : public Error {
public:
    using Error::Error;
};

/// Failure reported by a dependency at run time (Embree device, OpenEXR, FFTW).
class RuntimeFailure : public Error {
public:
    using Error::Error;
};

/// A render stopped by its caller (RenderSettings::abort) before it had an image to return.
class Interrupted : public Error {
public:
    using Error::Error;
};

}  // namespace gdr
