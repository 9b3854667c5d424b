// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/config/yaml_key_at_line.hpp"

#include <algorithm>
#include <climits>
#include <string_view>
#include <vector>

namespace fnmpc::config {
namespace {

/// The block structure of one line: indentation, sequence marker and key.
struct Line {
  bool blank = true;  ///< empty or a comment
  int dash = -1;      ///< column of the first "- " sequence marker, -1 if none
  int content = 0;    ///< column of the first character after indentation and markers
  std::string key;    ///< "k" when the content starts with "k:" and a blank or the line end
};

bool IsKeyChar(char c) {
  return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
         c == '-' || c == '.';
}

/// Change of the flow-collection depth ('[', '{' minus ']', '}') over line `s`, outside
/// quotes and comments.
int FlowDepthChange(std::string_view s) {
  int change = 0;
  char quote = 0;
  for (std::size_t i = 0; i < s.size(); ++i) {
    const char c = s[i];
    if (quote != 0) {
      if (c == quote) quote = 0;
    } else if (c == '\'' || c == '"') {
      quote = c;
    } else if (c == '#' && (i == 0 || s[i - 1] == ' ' || s[i - 1] == '\t')) {
      break;
    } else if (c == '[' || c == '{') {
      ++change;
    } else if (c == ']' || c == '}') {
      --change;
    }
  }
  return change;
}

/// Classifies line `s`; `flow_depth` is the number of flow collections still open before it
/// (a line inside one is a continuation, whatever it looks like) and is updated.
Line Classify(std::string_view s, int* flow_depth) {
  Line l;
  if (!s.empty() && s.back() == '\r') s.remove_suffix(1);
  const bool continuation = *flow_depth > 0;
  *flow_depth = std::max(0, *flow_depth + FlowDepthChange(s));
  std::size_t i = s.find_first_not_of(' ');
  if (i == std::string_view::npos || s[i] == '#') return l;
  l.blank = false;
  if (continuation) {
    l.content = static_cast<int>(i);
    return l;
  }
  while (i < s.size() && s[i] == '-' && (i + 1 == s.size() || s[i + 1] == ' ')) {
    if (l.dash < 0) l.dash = static_cast<int>(i);
    i = std::min(s.find_first_not_of(' ', i + 1), s.size());
  }
  l.content = static_cast<int>(i);
  std::size_t e = i;
  while (e < s.size() && IsKeyChar(s[e])) ++e;
  if (e > i && e < s.size() && s[e] == ':' &&
      (e + 1 == s.size() || s[e + 1] == ' ' || s[e + 1] == '\t')) {
    l.key = std::string(s.substr(i, e - i));
  }
  return l;
}

bool IsNode(const Line& l) { return !l.blank && (!l.key.empty() || l.dash >= 0); }

/// Column at which a node line's own content starts (its key, or its sequence marker).
int NodeColumn(const Line& l) { return l.key.empty() ? l.dash : l.content; }

/// Index of the nearest key line above `from` whose key column passes `encloses`, or -1.
template <typename Pred>
int KeyAbove(const std::vector<Line>& lines, int from, Pred encloses) {
  for (int k = from - 1; k >= 0; --k) {
    if (!lines[k].key.empty() && encloses(lines[k].content)) return k;
  }
  return -1;
}

/// Number of sequence items with their marker at column `dash` in lines (parent, last].
int ItemIndex(const std::vector<Line>& lines, int parent, int last, int dash) {
  int count = 0;
  for (int k = parent + 1; k <= last; ++k) count += lines[k].dash == dash ? 1 : 0;
  return count - 1;
}

/// "[i]".
std::string Index(int i) {
  std::string s(1, '[');
  s.append(std::to_string(i));
  s.push_back(']');
  return s;
}

/// Path of node line `n`: walks up through the enclosing keys (a loop, not recursion, so a
/// pathologically deep indentation cannot exhaust the stack).
std::string PathOf(const std::vector<Line>& lines, int n) {
  std::vector<std::string> suffixes;  // from `n` up to the top level
  while (n >= 0) {
    const Line& l = lines[n];
    if (l.key.empty()) {  // a sequence item "- ...": its parent key may share its column
      const int parent = KeyAbove(lines, n, [&](int c) { return c <= l.dash; });
      suffixes.push_back(Index(ItemIndex(lines, parent, n, l.dash)));
      n = parent;
      continue;
    }
    const int parent = KeyAbove(lines, n, [&](int c) { return c < l.content; });
    // The mapping holding this key is a sequence item when its first key follows a "- ".
    std::string suffix;
    for (int k = n; k > parent; --k) {
      if (!lines[k].key.empty() && lines[k].content == l.content && lines[k].dash >= 0) {
        suffix = Index(ItemIndex(lines, parent, k, lines[k].dash));
        break;
      }
    }
    suffix.push_back('.');
    suffix.append(l.key);
    suffixes.push_back(std::move(suffix));
    n = parent;
  }
  std::string path;
  for (auto it = suffixes.rbegin(); it != suffixes.rend(); ++it) path.append(*it);
  if (!path.empty() && path.front() == '.') path.erase(0, 1);
  return path;
}

}  // namespace

std::string YamlKeyAtLine(const std::string& text, int line) {
  std::vector<Line> lines;
  std::size_t start = 0;
  int flow_depth = 0;
  while (start <= text.size() && static_cast<int>(lines.size()) < std::max(line, 1)) {
    const std::size_t end = std::min(text.find('\n', start), text.size());
    lines.push_back(Classify(std::string_view(text).substr(start, end - start), &flow_depth));
    start = end + 1;
  }
  int n = static_cast<int>(lines.size()) - 1;  // the line, or the last one when beyond the end
  if (n < 0) return kTopLevelKey;
  if (!IsNode(lines[n])) {
    // A blank line belongs to the node above it, a continuation to the node enclosing it.
    const int column = lines[n].blank ? INT_MAX : lines[n].content;
    int k = n - 1;
    while (k >= 0 && !(IsNode(lines[k]) && NodeColumn(lines[k]) < column)) --k;
    if (k < 0) return kTopLevelKey;
    n = k;
  }
  return PathOf(lines, n);
}

}  // namespace fnmpc::config
