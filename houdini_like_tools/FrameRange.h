// SPDX-License-Identifier: Apache-2.0
// levelforge operators — frame sequences: `--frames A-B[:step]` and the frame tokens of paths.
//
// Tokens (Houdini and printf conventions), replaced by the frame number in every input, output
// and text parameter of a cook:
//   $F      the frame, e.g. 7            ${F}   the same, delimited
//   $F4     the frame padded to 4 digits ("0007"; any width 1-9: $F2, $F6, ...)
//   %d      the frame                    %04d   padded to 4 digits (any width 1-9)
// A negative frame keeps its sign in front of the padding ($F4 of -7 is "-007", like printf).
// "$$" and "%%" stand for a literal '$' and '%' in a path that has tokens.
#pragma once

#include <string>
#include <vector>

namespace levelforge::ops {

/// The frames of `--frames`: first..last (inclusive) every step.
struct FrameRange
{
    int first = 1, last = 1, step = 1;
    /// The frame numbers, in increasing order.
    std::vector<int> frames() const;
    /// "1-240", "1-240:2", "7".
    std::string text() const;
};

/// @brief Parses "A", "A-B" or "A-B:step" (integers; A <= B; step >= 1; at most 1,000,000 frames).
/// @throws UsageError naming --frames and the text
FrameRange parseFrameRange(const std::string& text);

/// True if @p text contains a frame token.
bool hasFrameToken(const std::string& text);

/// @p text with every frame token replaced by @p frame ("$$" -> "$", "%%" -> "%" when it has
/// tokens; text without tokens is returned unchanged).
std::string substituteFrame(const std::string& text, int frame);

} // namespace levelforge::ops
