// Registry::load_library / load_directory: external plugins as shared objects (see plugin.hpp).
//
// A library is all-or-nothing: it is dlopen()ed, every descriptor it enumerates is validated
// (descriptor_fault(): the same rules as for built-ins, ABI version first; then name clashes with
// what is already registered and within the library), and only then are they added. A refused library is dlclose()d and leaves
// the registry as it was. An accepted library's handle stays open in `libraries_` until the
// registry is destroyed (after every instance it created is gone).
//
// Plugins are code that locusd runs, often as a service user with CAP_SYS_NICE: a library or a plugin
// directory that anyone on the machine can write is refused (with the chmod that fixes it), as sshd's
// StrictModes refuses a world-writable authorized_keys. Only the files named or found in the configured
// directories are loaded; nothing is searched for on a library path.
#include <dlfcn.h>
#include <sys/stat.h>

#include <algorithm>
#include <cstdio>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include "locus/registry.hpp"

#include "descriptor_rules.hpp"

namespace locus {

namespace {

namespace fs = std::filesystem;

/// A library enumerating more descriptors than this is assumed to be missing its nullptr sentinel.
constexpr std::uint32_t kMaxDescriptorsPerLibrary = 256;

/// Closes a dlopen handle unless released (refused libraries never stay loaded).
class LibraryHandle {
 public:
  explicit LibraryHandle(void* handle) noexcept : handle_(handle) {}
  ~LibraryHandle() {
    if (handle_ != nullptr) ::dlclose(handle_);
  }
  LibraryHandle(const LibraryHandle&) = delete;
  LibraryHandle& operator=(const LibraryHandle&) = delete;
  void* get() const noexcept { return handle_; }
  void* release() noexcept {
    void* h = handle_;
    handle_ = nullptr;
    return h;
  }

 private:
  void* handle_;
};

std::string describe(const locus_plugin_descriptor& d, std::uint32_t index) {
  if (d.name != nullptr) return "descriptor '" + std::string(d.name) + "'";
  return "descriptor #" + std::to_string(index);
}

/// A broken descriptor rule, as a library's error says it (the ABI in the library's terms, since a
/// rebuild is the fix; a null name by index).
std::string fault_message(const locus_plugin_descriptor& d, std::uint32_t index, const DescriptorFault& fault) {
  switch (fault.rule) {
    case DescriptorRule::AbiVersion:
      return "descriptor #" + std::to_string(index) + " was built for Locus plugin ABI " +
             std::to_string(d.abi_version) + ", this host speaks ABI " + std::to_string(LOCUS_PLUGIN_ABI_VERSION) +
             "; rebuild the plugin against this Locus (find_package(Locus))";
    case DescriptorRule::NameNotNull: return "descriptor #" + std::to_string(index) + " has a null name";
    default: return describe(d, index) + ": " + fault.reason;
  }
}

/// dlerror() text without a leading "<path>: " (the message already names the file).
std::string dl_reason(const std::string& dlopen_path) {
  const char* e = ::dlerror();
  std::string reason = e != nullptr ? e : "unknown dynamic loader error";
  const std::string prefix = dlopen_path + ": ";
  if (reason.compare(0, prefix.size(), prefix) == 0) reason.erase(0, prefix.size());
  return reason;
}

/// Why `path` (a library or the directory holding libraries) may not be trusted: it is world-writable,
/// so anyone could replace or add code. Empty when it is fine. Follows symlinks: the target is what
/// gets loaded.
std::string writable_by_others(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return {};
  if ((st.st_mode & S_IWOTH) == 0) return {};
  char mode[8];
  std::snprintf(mode, sizeof mode, "%04o", static_cast<unsigned>(st.st_mode & 07777));
  return std::string("is world-writable (mode ") + mode + "): anyone on this machine could change the code "
         "locusd runs; refused (fix: chmod o-w " + path + ")";
}

}  // namespace

std::vector<std::string> Registry::load_library(const std::string& path) {
  const auto error = [&path](const std::string& reason) {
    return PluginLoadError("plugin library " + path + ": " + reason);
  };

  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (ec || !fs::exists(status)) throw error("no such file");
  if (fs::is_directory(status)) throw error("is a directory, not a shared object");
  if (const std::string why = writable_by_others(path); !why.empty()) throw error(why);
  const fs::path parent = fs::absolute(fs::path(path), ec).parent_path();
  if (!ec) {
    if (const std::string why = writable_by_others(parent.string()); !why.empty()) {
      throw error("its directory " + parent.string() + " " + why);
    }
  }

  // dlopen() searches the library path for a name without a '/'; always hand it a real path.
  std::string dlopen_path = path;
  if (dlopen_path.find('/') == std::string::npos) dlopen_path = "./" + dlopen_path;

  ::dlerror();  // clear any stale error
  LibraryHandle handle(::dlopen(dlopen_path.c_str(), RTLD_NOW | RTLD_LOCAL));
  if (handle.get() == nullptr) throw error("cannot be loaded as a shared object: " + dl_reason(dlopen_path));

  ::dlerror();
  void* symbol = ::dlsym(handle.get(), LOCUS_PLUGIN_ENUM_SYMBOL);
  if (symbol == nullptr) {
    throw error("no entry point '" LOCUS_PLUGIN_ENUM_SYMBOL
                "' (not a Locus plugin; a plugin defines it with LOCUS_PLUGIN_EXPORT from locus/plugin.hpp)");
  }
  const auto enumerate = reinterpret_cast<locus_plugin_enum_fn>(symbol);

  // Validate everything before adding anything.
  std::vector<const locus_plugin_descriptor*> descriptors;
  for (std::uint32_t index = 0;; ++index) {
    if (index == kMaxDescriptorsPerLibrary) {
      throw error("enumerates more than " + std::to_string(kMaxDescriptorsPerLibrary) +
                  " descriptors (" LOCUS_PLUGIN_ENUM_SYMBOL " must return nullptr past the last one)");
    }
    const locus_plugin_descriptor* d = nullptr;
    try {
      d = enumerate(index);
    } catch (...) {
      throw error(LOCUS_PLUGIN_ENUM_SYMBOL "(" + std::to_string(index) + ") threw an exception");
    }
    if (d == nullptr) break;

    // The descriptor rules (descriptor_rules.hpp), worded for a library: by index until the name is known.
    if (const auto fault = descriptor_fault(d)) throw error(fault_message(*d, index, *fault));
    const std::string what = describe(*d, index);
    const std::string_view name(d->name);
    for (const locus_plugin_descriptor* earlier : descriptors) {
      if (name == earlier->name) throw error(what + " is enumerated twice by this library");
    }
    for (const PluginEntry& entry : plugins_) {
      if (entry.descriptor != nullptr && entry.descriptor->name != nullptr && name == entry.descriptor->name) {
        throw error("plugin name '" + std::string(name) + "' is already registered (" +
                    (entry.origin == "built-in" ? std::string("built-in") : "loaded from " + entry.origin) + ")");
      }
    }
    descriptors.push_back(d);
  }
  if (descriptors.empty()) throw error(LOCUS_PLUGIN_ENUM_SYMBOL " enumerates no plugins");

  // Add them all, or none: add_plugin validates again and may still refuse one.
  const std::size_t before = plugins_.size();
  std::vector<std::string> names;
  names.reserve(descriptors.size());
  try {
    for (const locus_plugin_descriptor* d : descriptors) {
      add_plugin(d, path);
      names.emplace_back(d->name);
    }
    libraries_.push_back(handle.get());
  } catch (const std::exception& e) {
    plugins_.erase(plugins_.begin() + static_cast<std::ptrdiff_t>(before), plugins_.end());
    const std::string reason = e.what();
    // add_plugin's messages may or may not name the file already.
    if (reason.find(path) != std::string::npos) throw PluginLoadError(reason);
    throw error(reason);
  }
  handle.release();
  return names;
}

std::vector<std::string> Registry::load_directory(const std::string& dir) {
  std::vector<std::string> failures;
  std::error_code ec;
  const fs::file_status status = fs::status(dir, ec);
  if (ec || !fs::exists(status)) {
    failures.push_back("plugin directory " + dir + ": no such directory");
    return failures;
  }
  if (!fs::is_directory(status)) {
    failures.push_back("plugin directory " + dir + ": not a directory");
    return failures;
  }
  if (const std::string why = writable_by_others(dir); !why.empty()) {
    failures.push_back("plugin directory " + dir + ": " + why);
    return failures;
  }

  std::vector<fs::path> libraries;
  fs::directory_iterator it(dir, ec);
  if (ec) {
    failures.push_back("plugin directory " + dir + ": cannot be read: " + ec.message());
    return failures;
  }
  for (const fs::directory_entry& entry : it) {
    const fs::path& p = entry.path();
    if (p.extension() != ".so") continue;
    std::error_code type_ec;
    if (entry.is_directory(type_ec)) continue;
    libraries.push_back(p);
  }
  std::sort(libraries.begin(), libraries.end(),
            [](const fs::path& a, const fs::path& b) { return a.filename().native() < b.filename().native(); });

  for (const fs::path& p : libraries) {
    try {
      load_library(p.string());
    } catch (const PluginLoadError& e) {
      failures.emplace_back(e.what());
    }
  }
  return failures;
}

}  // namespace locus
