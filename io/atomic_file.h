// Output that appears whole or not at all: write to a temporary name in the same folder, then
// rename over the final name (atomic on POSIX). A killed run leaves no half-written file.
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace penumbra {

// A temporary sibling of `path` that keeps its extension (".name.tmp-PID.ext"), for writers such
// as OpenImageIO that pick the format from it.
std::string temporarySibling(const std::string& path);
// Renames `temporary` to `path`; throws Error on failure (and removes the temporary).
void commitFile(const std::string& temporary, const std::string& path);
// Writes `contents` to `path` atomically.
void writeFileAtomic(const std::string& path, const std::string& contents);
// The parts one after the other (no copy of them joined).
void writeFileAtomic(const std::string& path, const std::vector<std::string_view>& parts);
// Creates `dir` (and parents) if missing; throws Error naming it if that fails or it is a file.
void ensureDirectory(const std::string& dir);

}  // namespace penumbra
