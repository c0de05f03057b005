// Which external files a scene may make the loader read. A scene is untrusted input (docs/SECURITY.md): a
// buffer URI such as "../../home/user/.ssh/id_rsa" would otherwise carry any readable file of the machine
// into the baked asset. By default a URI must be a relative path that stays, symbolic links resolved,
// inside a root folder: the scene's own, or a batch's input root.
#pragma once

#include <string>

namespace cb {

// Empty when `uri` (as written in the file) names a file inside `root` once joined to `base_dir`, else why
// not, in a few words ("a '..' leads out of the scene's folder"). `root_name` says what the root is in that
// reason. URIs with a scheme (file:, http:) and absolute paths are refused whatever they name.
std::string outside_root_problem(const std::string& uri, const std::string& base_dir, const std::string& root,
                                 const std::string& root_name);

// Empty when the file at `path` (symbolic links resolved) lies inside `root`, else why not.
std::string path_outside_root(const std::string& path, const std::string& root, const std::string& root_name);

// "%20" and the like in a URI decoded, as glTF readers decode them before opening the file.
std::string percent_decoded(const std::string& uri);

}  // namespace cb
