// A minimal JSON reader, enough for HAPI's .header files (internal).
#pragma once

#include <map>
#include <memory>
#include <string>
#include <vector>

namespace qogi {

struct JsonValue {
  enum class Kind { kNull, kBool, kNumber, kString, kArray, kObject };
  Kind kind = Kind::kNull;
  bool boolean = false;
  double number = 0;
  std::string string;
  std::vector<JsonValue> array;
  std::map<std::string, JsonValue> object;

  // The member `key` of an object, or nullptr.
  const JsonValue* Find(const std::string& key) const;
};

// Parses a JSON document; throws std::runtime_error("<what>: ...") with the
// byte offset of the first syntax error.
JsonValue ParseJson(const std::string& text, const std::string& what);

}  // namespace qogi
