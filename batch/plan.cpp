#include "plan.h"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <istream>
#include <map>

#include "load.h"

namespace fs = std::filesystem;

namespace cb {
namespace {

std::string output_for(const std::string& outdir, const std::string& name) {
    return (fs::path(outdir) / fs::path(name).replace_extension(".cbk")).string();
}

uint64_t size_of(const fs::path& p) {
    std::error_code ec;
    uintmax_t n = fs::file_size(p, ec);
    return ec ? 0 : uint64_t(n);
}

void add_folder(const fs::path& root, const std::string& outdir, std::vector<BatchJob>& jobs) {
    std::error_code ec;
    size_t before = jobs.size();
    fs::recursive_directory_iterator it(root, fs::directory_options::none, ec), end;
    if (ec) throw PlanError(root.string() + ": cannot list (" + ec.message() + ")");
    for (; it != end; it.increment(ec)) {
        if (ec) throw PlanError(root.string() + ": cannot list (" + ec.message() + ")");
        if (!it->is_regular_file(ec) || !is_scene_path(it->path().string())) continue;
        BatchJob job;
        job.name = it->path().lexically_relative(root).generic_string();
        job.input = it->path().string();
        job.root = root.string();
        job.output = output_for(outdir, job.name);
        job.origin = root.string();
        job.input_size = size_of(it->path());
        jobs.push_back(std::move(job));
    }
    if (jobs.size() == before) throw PlanError(root.string() + ": no scene files (.gltf .glb .obj .ply .off .stl)");
}

void add_manifest(std::istream& in, const std::string& where, const fs::path& root, const std::string& outdir,
                  std::vector<BatchJob>& jobs) {
    size_t number = 0;
    for (std::string line; std::getline(in, line);) {
        ++number;
        std::string at = where + ": line " + std::to_string(number);
        std::vector<std::string> fields;
        try {
            fields = manifest_fields(line);
        } catch (const PlanError& e) {
            throw PlanError(at + ": " + e.what());
        }
        if (fields.empty()) continue;
        // A relative path is placed lexically (a symbolic link inside the tree keeps its place in it).
        fs::path given(fields[0]), path = given.is_absolute() ? given : root / given;
        fs::path name = given.is_absolute() ? fs::weakly_canonical(path).lexically_relative(fs::weakly_canonical(root))
                                            : path.lexically_normal().lexically_relative(root.lexically_normal());
        if (name.empty() || *name.begin() == "..")
            throw PlanError(at + ": " + fields[0] + " is outside the manifest's folder, so no output path mirrors it");
        if (!is_scene_path(path.string()))
            throw PlanError(at + ": " + fields[0] + " is not a scene file (.gltf .glb .obj .ply .off .stl)");
        BatchJob job;
        job.name = name.generic_string();
        job.input = path.string();
        job.root = root.string();
        job.output = output_for(outdir, job.name);
        job.args.assign(fields.begin() + 1, fields.end());
        job.origin = at;
        job.input_size = size_of(path);
        jobs.push_back(std::move(job));
    }
    if (in.bad()) throw PlanError(where + ": read error");
}

}  // namespace

bool is_scene_path(const std::string& path) { return format_from_path(path) != FileFormat::unknown; }

std::vector<std::string> manifest_fields(const std::string& line) {
    std::vector<std::string> fields;
    size_t i = 0, n = line.size();
    auto blank = [](char c) { return c == ' ' || c == '\t' || c == '\r'; };
    while (true) {
        while (i < n && blank(line[i])) ++i;
        if (i == n || (fields.empty() && line[i] == '#')) break;
        std::string field;
        while (i < n && !blank(line[i])) {
            if (line[i] == '"' || line[i] == '\'') {
                size_t close = line.find(line[i], i + 1);
                if (close == std::string::npos) throw PlanError("unclosed quote");
                field += line.substr(i + 1, close - i - 1);
                i = close + 1;
            } else {
                field += line[i++];
            }
        }
        fields.push_back(field);
    }
    return fields;
}

std::vector<BatchJob> plan_batch(const std::vector<std::string>& inputs, const std::string& outdir,
                                 std::istream* manifest_stdin) {
    std::vector<BatchJob> jobs;
    for (const std::string& input : inputs) {
        if (input == "-") {
            if (!manifest_stdin) throw PlanError("-: no standard input to read a manifest from");
            add_manifest(*manifest_stdin, "standard input", fs::current_path(), outdir, jobs);
            continue;
        }
        std::error_code ec;
        fs::file_status status = fs::status(input, ec);
        if (!fs::exists(status)) throw PlanError(input + ": no such file or folder");
        if (fs::is_directory(status)) {
            add_folder(fs::path(input), outdir, jobs);
        } else if (is_scene_path(input)) {
            BatchJob job;
            job.name = fs::path(input).filename().string();
            job.input = input;
            // A file named on the command line is taken where it lies (even through a link); its external
            // files must lie in its folder, as for `bake`: no root.
            job.output = output_for(outdir, job.name);
            job.origin = input;
            job.input_size = size_of(input);
            jobs.push_back(std::move(job));
        } else {
            std::ifstream in(input);
            if (!in) throw PlanError(input + ": cannot open");
            fs::path root = fs::path(input).parent_path();
            add_manifest(in, input, root.empty() ? fs::path(".") : root, outdir, jobs);
        }
    }
    // Sorted by name, then by input path; the same file named twice (a folder and a file in it) is one job.
    std::stable_sort(jobs.begin(), jobs.end(), [](const BatchJob& a, const BatchJob& b) { return a.name < b.name; });
    std::vector<BatchJob> unique;
    std::map<std::string, size_t> by_output;
    for (BatchJob& job : jobs) {
        auto [at, fresh] = by_output.emplace(job.output, unique.size());
        if (fresh) {
            unique.push_back(std::move(job));
            continue;
        }
        const BatchJob& first = unique[at->second];
        std::error_code ec;
        if (fs::equivalent(first.input, job.input, ec) && first.args == job.args) continue;
        throw PlanError(first.input + " and " + job.input + " would both write " + job.output);
    }
    return unique;
}

}  // namespace cb
