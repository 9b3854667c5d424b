// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <string>

namespace fnmpc::config {

/// Pseudo-key of errors about the document as a whole (a top level that is not a mapping, a
/// syntax error before or outside every key).
inline constexpr const char* kTopLevelKey = "(top level)";

/// Dotted key path ("vehicles[1].neighbours[0]", "controller.horizon") of the block-style
/// YAML node that line `line` (1-based) of `text` belongs to, read from the text's
/// indentation alone, so it also works for text that yaml-cpp refused. A line holding
/// `key:` names that key; a `- ` sequence item names its index; a blank or continuation line
/// belongs to the nearest key above it that encloses it. Returns kTopLevelKey when the line
/// lies in no key. Used to give syntax, encoding and structure errors the key of the region
/// they fall in (every rejection names file, line and key: docs/failure.md).
std::string YamlKeyAtLine(const std::string& text, int line);

}  // namespace fnmpc::config
