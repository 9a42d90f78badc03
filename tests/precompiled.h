// The headers nearly every test includes, parsed once per test program
// (target_precompile_headers): GoogleTest, nlohmann-json, Eigen and the
// solver's world parse for longer than most test files compile.
#pragma once

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "import/mesh_sampler.h"
#include "import/scene_loader.h"
#include "sim/solver.h"
#include "sim/world.h"
