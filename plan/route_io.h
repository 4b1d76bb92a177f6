// route.json (docs/formats.md, "Route"): what `waymark route` writes and `waymark sim --drive`
// reads.
#pragma once

#include <filesystem>
#include <string>

#include "plan/route.h"

namespace waymark::plan {

std::string FormatRoute(const Route& route);
// Strict reader: a FormatError "path:line: field: message" for anything but a route with at
// least one waypoint of finite x, y, yaw.
Route ParseRoute(const std::string& text, const std::filesystem::path& path);
Route ReadRoute(const std::filesystem::path& path);

}  // namespace waymark::plan
