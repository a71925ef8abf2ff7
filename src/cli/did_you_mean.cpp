#include "cli/did_you_mean.hpp"

#include <algorithm>
#include <cctype>
#include <cstdlib>

namespace bgkmap::cli {

namespace {

// The spelling names are compared in: lower case, underscores as dashes.
std::string folded(std::string name) {
  for (char& c : name) c = c == '_' ? '-' : static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return name;
}

size_t leading_dashes(const std::string& name) { return std::min(name.find_first_not_of('-'), name.size()); }

// A negative number is a value, not a flag.
bool looks_like_flag(const std::string& arg) {
  if (arg.size() < 2 || arg[0] != '-') return false;
  char* end = nullptr;
  std::strtod(arg.c_str(), &end);
  return *end != '\0';
}

std::string flag_name(const std::string& arg) { return arg.substr(0, arg.find('=')); }

std::vector<std::string> flag_names(const CLI::App& app) {
  std::vector<std::string> names;
  for (const CLI::Option* opt : app.get_options()) {
    for (const std::string& s : opt->get_snames()) names.push_back("-" + s);
    for (const std::string& l : opt->get_lnames()) names.push_back("--" + l);
  }
  return names;
}

std::string suggestion(const std::string& typed, const std::vector<std::string>& known) {
  const std::string best = closest_name(typed, known);
  return best.empty() ? "" : "; did you mean '" + best + "'?";
}

// "unknown flag '--max_range'; did you mean '--max-range'?", else the flag and `otherwise`.
std::string unknown_flag(const CLI::App& app, const std::string& arg, const std::string& otherwise) {
  const std::string name = flag_name(arg);
  const std::string hint = suggestion(name, flag_names(app));
  return "unknown flag '" + name + "'" + (hint.empty() ? otherwise : hint);
}

std::string unknown_subcommand(const CLI::App& app, const std::string& typed) {
  std::vector<std::string> names;
  for (const CLI::App* sub : app.get_subcommands([](const CLI::App* s) { return !s->get_name().empty(); }))
    names.push_back(sub->get_name());
  const std::string hint = suggestion(typed, names);
  if (!hint.empty()) return "unknown subcommand '" + typed + "'" + hint;
  std::string list;
  for (const std::string& n : names) list += (list.empty() ? "" : ", ") + n;
  return "unknown subcommand '" + typed + "' (the subcommands: " + list + ")";
}

}  // namespace

size_t edit_distance(const std::string& a, const std::string& b) {
  // Optimal string alignment: rows i-2, i-1 and i of the table.
  std::vector<size_t> before(b.size() + 1), last(b.size() + 1), row(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) last[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    row[0] = i;
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t cost = a[i - 1] == b[j - 1] ? 0 : 1;
      row[j] = std::min({last[j] + 1, row[j - 1] + 1, last[j - 1] + cost});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1]) row[j] = std::min(row[j], before[j - 2] + 1);
    }
    std::swap(before, last);
    std::swap(last, row);
  }
  return last[b.size()];
}

std::string closest_name(const std::string& typed, const std::vector<std::string>& known) {
  const std::string t = folded(typed);
  const size_t typed_length = t.size() - leading_dashes(t);
  // A third of the letters may be wrong; a one- or two-letter name only in case or underscores.
  size_t best_distance = typed_length / 3 + 1;
  std::string best;
  std::vector<std::string> extended;  // the names `typed` begins
  for (const std::string& name : known) {
    const std::string n = folded(name);
    const size_t d = edit_distance(t, n);
    if (d < best_distance) {
      best_distance = d;
      best = name;
    }
    if (typed_length >= 3 && n.size() > t.size() && n.compare(0, t.size(), t) == 0) extended.push_back(name);
  }
  if (best.empty() && extended.size() == 1) return extended.front();
  return best;
}

std::optional<std::string> unknown_name_error(const CLI::App& app) {
  const std::vector<CLI::App*> parsed = app.get_subcommands();
  if (parsed.empty()) {
    const std::vector<std::string> extra = app.remaining();
    if (extra.empty()) return std::nullopt;
    if (looks_like_flag(extra.front()))
      return unknown_flag(app, extra.front(), " (a subcommand's flags follow it: bgkmap SUBCOMMAND --help)");
    return unknown_subcommand(app, extra.front());
  }
  const CLI::App& sub = *parsed.front();
  for (const std::string& arg : sub.remaining())
    if (looks_like_flag(arg))
      return sub.get_name() + ": " + unknown_flag(sub, arg, " (see bgkmap " + sub.get_name() + " --help)");
  return std::nullopt;
}

}  // namespace bgkmap::cli
