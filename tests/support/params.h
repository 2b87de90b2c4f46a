// RIB parameters as the parser gives them, for tests and benchmarks that
// build scene records by hand.
#pragma once

#include "umbra/ri/param_list.h"

#include <string>
#include <utility>
#include <vector>

namespace umbra::testsupport {

/// A float-valued parameter (float, point, color, ...), uniform unless said.
inline ri::Param floatParam(const std::string& name, ri::ParamType type, std::vector<float> values,
                            ri::StorageClass storage = ri::StorageClass::Uniform, int arraySize = 1) {
    ri::Param p;
    p.decl.name = name;
    p.decl.storage = storage;
    p.decl.type = type;
    p.decl.arraySize = arraySize;
    p.floats = std::move(values);
    return p;
}

/// The vertex positions "P".
inline ri::Param pointParam(std::vector<float> values) {
    return floatParam("P", ri::ParamType::Point, std::move(values), ri::StorageClass::Vertex);
}

}  // namespace umbra::testsupport
