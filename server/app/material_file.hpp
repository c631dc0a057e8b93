// Material files (TOML): areal density and the weft, warp and shear spline laws.
#pragma once

#include <string>

#include "app/toml_file.hpp"
#include "cloth/material.hpp"

namespace hapticloth::app {

/// Loads a material file. Throws ConfigError naming file, line and key on bad input.
cloth::Material load_material(const std::string& path);
cloth::Material parse_material(const TomlFile& file);

/// Writes a material in the same format (used by the fitting tool and tests).
std::string format_material(const cloth::Material& m, const std::string& comment = "");

}  // namespace hapticloth::app
