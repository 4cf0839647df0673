// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief The three Boolean operations on signed distance fields (negative inside), shared by
///        the CSG of level sets (levelset/LevelSetCsg.h) and of adaptive distance fields
///        (adf/AdaptiveDistanceField.h): union min(a, b), intersection max(a, b), difference
///        max(a, -b), the min/max rules of Ricci, "A Constructive Geometry for Computer
///        Graphics", The Computer Journal 16(2), 1973.
#pragma once

#include <string>

namespace levelforge {

/// A Boolean operation on two signed distance fields a and b.
enum class CsgOperation
{
    Union,        ///< min(a, b)
    Intersection, ///< max(a, b)
    Difference    ///< max(a, -b): a without b
};

/// @brief The operation named @p name.
/// @param[in] name  "union", "intersection" or "difference"
/// @return the operation
/// @throws InvalidArgumentError for any other name
CsgOperation csgOperationFromString(const std::string& name);

/// @brief The name of @p op, as csgOperationFromString() reads it.
/// @param[in] op  the operation
/// @return "union", "intersection" or "difference"
const char* csgOperationName(CsgOperation op);

} // namespace levelforge
