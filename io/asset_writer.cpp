#include "asset_writer.h"

#include <cerrno>
#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <new>
#include <algorithm>
#include <atomic>
#include <thread>
#include <list>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <type_traits>
#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include "free_storage.h"

namespace cb {
namespace {

template <class T>
void append(std::vector<uint8_t>& out, const T* data, size_t count) {
    const uint8_t* p = reinterpret_cast<const uint8_t*>(data);
    out.insert(out.end(), p, p + count * sizeof(T));
}

EncodedMesh encode_mesh(const AssetMesh& m) {
    EncodedMesh out;
    const uint32_t unseen = UINT32_MAX;
    const size_t vertices = m.positions.size() / 3;
    std::vector<uint32_t> renumbered(vertices, unseen);
    // Per vertex, the fine cluster that last listed it (its index + 1) and its slot there: below `reuse`,
    // the n-th new vertex; from `reuse` on, the n-th reused one. Linear, where searching the cluster's
    // list of reused vertices for every corner was not.
    std::vector<uint32_t> listed(vertices, 0);
    std::vector<uint16_t> slot(vertices, 0);
    constexpr uint16_t reuse = 0x100;
    std::vector<uint32_t> reused;  // the current cluster's earlier vertices, in order of first use
    uint32_t next = 0;
    const size_t corners = m.triangles.size(), ahead = 24;
    out.positions.reserve(m.positions.size() + m.positions.size() / 8);  // some vertices are stored twice
    out.local.reserve(m.triangles.size());
    out.fine.reserve(m.fine.size());
    for (size_t c = 0; c < m.fine.size(); ++c) {
        const ClusterRange& r = m.fine[c];
        if (r.count == 0 || r.count > 255)
            throw std::invalid_argument("a fine cluster holds " + std::to_string(r.count) +
                                        " triangles (1 to 255 can be stored)");
        const uint32_t mark = uint32_t(c) + 1;
        FineCluster f{};
        f.first_triangle = r.first;
        f.first_vertex = next;
        f.first_ref = uint32_t(out.refs.size());
        f.triangle_count = uint8_t(r.count);
        // New vertices first, in order of first use, then reused ones in order of first use. A vertex too far
        // back for a 16-bit reference is stored again (same coordinates, so the same triangles).
        reused.clear();
        for (size_t i = size_t(r.first) * 3; i < (size_t(r.first) + r.count) * 3; ++i) {
            // A vertex's three entries and position lie anywhere in arrays larger than the cache: those of the
            // corner `ahead` on are asked for now, so that their misses overlap.
            if (i + ahead < corners) {
                const uint32_t u = m.triangles[i + ahead];
                __builtin_prefetch(&listed[u]);
                __builtin_prefetch(&renumbered[u]);
                __builtin_prefetch(&m.positions[size_t(u) * 3]);
            }
            const uint32_t v = m.triangles[i];
            if (listed[v] == mark) continue;
            listed[v] = mark;
            if (renumbered[v] == unseen || f.first_vertex - renumbered[v] > 65535) {
                slot[v] = uint16_t(next - f.first_vertex);
                renumbered[v] = next++;
                const float* p = &m.positions[size_t(v) * 3];
                out.positions.insert(out.positions.end(), {p[0], p[1], p[2]});
            } else {
                slot[v] = uint16_t(reuse + reused.size());
                reused.push_back(renumbered[v]);
            }
        }
        uint32_t fresh = next - f.first_vertex;
        if (fresh + reused.size() > max_cluster_vertices)
            throw std::invalid_argument("a fine cluster uses more than " + std::to_string(max_cluster_vertices) +
                                        " vertices");
        f.vertex_count = uint8_t(fresh);
        f.ref_count = uint8_t(reused.size());
        for (uint32_t t = r.first; t < r.first + r.count; ++t)
            for (int k = 0; k < 3; ++k) {
                uint16_t at = slot[m.triangles[size_t(t) * 3 + k]];
                out.local.push_back(uint8_t(at < reuse ? at : fresh + (at - reuse)));
            }
        for (uint32_t v : reused) out.refs.push_back(uint16_t(f.first_vertex - v));
        out.fine.push_back(f);
    }
    return out;
}

// An asset laid out but not yet assembled: the header (checksum still zero) and section table, and the
// sections' bytes with their offsets in the file, pointing at arrays that live here or in the meshes.
struct AssetLayout {
    std::vector<uint8_t> head;  // header and section table, up to the first section
    struct Part {
        const uint8_t* bytes;
        uint64_t size, offset;
    };
    std::vector<Part> parts;
    uint64_t file_size = 0;

    std::vector<MeshRecord> records;
    std::vector<float> positions;
    std::vector<uint8_t> triangles;
    std::vector<uint16_t> refs;
    std::vector<FineCluster> fine;
    std::vector<ClusterRange> coarse;
    std::vector<InstanceRecord> instances;
    std::vector<uint32_t> sided, flags;
    std::list<std::vector<uint8_t>> owned;
    // The parts from this one on are the volumes' and what follows them: written once the volumes are filled,
    // after `gathers` have copied the volumes of several meshes into their sections.
    size_t bounds_from = 0;
    std::vector<std::function<void(const std::vector<AssetMesh>&)>> gathers;
};

// Lays out the asset of `meshes`, whose encode_geometry is `geometry`. The bounds sections are those whose
// arrays every mesh has sized to its clusters; their bytes are read when written (a single mesh's straight
// from its arrays, several meshes' once `gathers` have run).
void lay_out(AssetLayout& L, const std::vector<AssetMesh>& meshes, std::vector<EncodedMesh> geometry,
             const std::vector<Instance>& instances, const std::string& source) {
    if (geometry.size() != meshes.size()) throw std::invalid_argument("encoded geometry of other meshes");
    // Concatenate every mesh's arrays; records hold each mesh's offsets into them.
    for (size_t i = 0; i < meshes.size(); ++i) {
        const AssetMesh& m = meshes[i];
        EncodedMesh& c = geometry[i];
        MeshRecord r{};
        r.first_vertex = uint32_t(L.positions.size() / 3);
        r.vertex_count = uint32_t(c.positions.size() / 3);
        r.first_triangle = uint32_t(L.triangles.size() / 3);
        r.triangle_count = uint32_t(c.local.size() / 3);  // the mesh's own triangles may be freed already
        r.first_fine = uint32_t(L.fine.size());
        r.fine_count = uint32_t(m.fine.size());
        r.first_coarse = uint32_t(L.coarse.size());
        r.coarse_count = uint32_t(m.coarse.size());
        r.first_ref = uint32_t(L.refs.size());
        r.ref_count = uint32_t(c.refs.size());
        L.records.push_back(r);
        if (meshes.size() == 1) {
            L.positions = std::move(c.positions);
            L.triangles = std::move(c.local);
            L.refs = std::move(c.refs);
            L.fine = std::move(c.fine);
        } else {
            L.positions.insert(L.positions.end(), c.positions.begin(), c.positions.end());
            L.triangles.insert(L.triangles.end(), c.local.begin(), c.local.end());
            L.refs.insert(L.refs.end(), c.refs.begin(), c.refs.end());
            L.fine.insert(L.fine.end(), c.fine.begin(), c.fine.end());
        }
        L.coarse.insert(L.coarse.end(), m.coarse.begin(), m.coarse.end());
        c = EncodedMesh{};
    }
    L.instances.resize(instances.size());
    for (size_t i = 0; i < instances.size(); ++i) {
        InstanceRecord& rec = L.instances[i];
        rec = InstanceRecord{};
        rec.mesh = instances[i].mesh;
        for (int col = 0; col < 4; ++col)
            for (int row = 0; row < 3; ++row) rec.transform[col * 3 + row] = instances[i].world[size_t(col) * 4 + row];
    }

    struct Pending {
        SectionType type;
        uint32_t element_size;
        const uint8_t* bytes;
        uint64_t size, count;
    };
    std::vector<Pending> sections;
    auto add = [&](SectionType type, const auto& v, uint32_t element_size) {
        uint64_t size = uint64_t(v.size()) * sizeof(v[0]);
        sections.push_back({type, element_size, reinterpret_cast<const uint8_t*>(v.data()), size, size / element_size});
    };
    add(SectionType::meshes, L.records, sizeof(MeshRecord));
    add(SectionType::positions, L.positions, 12);
    add(SectionType::triangles, L.triangles, 3);
    add(SectionType::vertex_refs, L.refs, 2);
    add(SectionType::fine_clusters, L.fine, sizeof(FineCluster));
    add(SectionType::coarse_clusters, L.coarse, sizeof(ClusterRange));
    add(SectionType::instances, L.instances, sizeof(InstanceRecord));

    // Sidedness, one bit per triangle of the whole triangle array (only when some triangle is double-sided),
    // and the per-mesh flags.
    L.sided.assign((L.triangles.size() / 3 + 31) / 32, 0);
    bool any_double_sided = false;
    for (size_t m = 0; m < meshes.size(); ++m) {
        L.flags.push_back(meshes[m].flags);
        for (size_t t = 0; t < meshes[m].double_sided.size(); ++t)
            if (meshes[m].double_sided[t]) {
                size_t bit = L.records[m].first_triangle + t;
                L.sided[bit / 32] |= 1u << (bit % 32);
                any_double_sided = true;
            }
    }
    if (any_double_sided) add(SectionType::double_sided, L.sided, 4);
    add(SectionType::mesh_flags, L.flags, 4);

    // Bounds: a section per volume kind and level that every mesh with clusters carries.
    auto level_section = [&](SectionType type, bool fine, auto member) {
        using Record = typename std::remove_reference_t<decltype(meshes[0].fine_volumes.*member)>::value_type;
        for (const AssetMesh& m : meshes) {
            const LevelVolumes& v = fine ? m.fine_volumes : m.coarse_volumes;
            size_t clusters = fine ? m.fine.size() : m.coarse.size();
            if ((v.*member).size() != clusters) return false;  // not fitted (for every mesh): no section
        }
        if (meshes.size() == 1) {  // the mesh's own array
            add(type, (fine ? meshes[0].fine_volumes : meshes[0].coarse_volumes).*member, sizeof(Record));
            return true;
        }
        std::vector<uint8_t>& owned = L.owned.emplace_back();
        size_t records = 0;
        for (const AssetMesh& m : meshes) records += ((fine ? m.fine_volumes : m.coarse_volumes).*member).size();
        owned.reserve(records * sizeof(Record));
        L.gathers.push_back([&owned, fine, member](const std::vector<AssetMesh>& filled) {
            owned.clear();
            for (const AssetMesh& m : filled) {
                const LevelVolumes& v = fine ? m.fine_volumes : m.coarse_volumes;
                append(owned, (v.*member).data(), (v.*member).size());
            }
        });
        sections.push_back({type, uint32_t(sizeof(Record)), owned.data(), records * sizeof(Record), records});
        return true;
    };
    L.bounds_from = sections.size();  // one part per section, in the same order
    for (bool fine : {true, false}) {
        bool boxes = level_section(fine ? SectionType::fine_obbs : SectionType::coarse_obbs, fine, &LevelVolumes::obbs);
        level_section(fine ? SectionType::fine_spheres : SectionType::coarse_spheres, fine, &LevelVolumes::spheres);
        level_section(fine ? SectionType::fine_capsules : SectionType::coarse_capsules, fine, &LevelVolumes::capsules);
        if (boxes)  // a cone's apexes are stored relative to its box
            level_section(fine ? SectionType::fine_cones : SectionType::coarse_cones, fine, &LevelVolumes::cones);
        level_section(fine ? SectionType::fine_slabs : SectionType::coarse_slabs, fine, &LevelVolumes::slabs);
    }

    if (!source.empty()) add(SectionType::source, source, 1);

    auto aligned = [](uint64_t x) { return (x + asset_alignment - 1) / asset_alignment * asset_alignment; };
    std::vector<SectionEntry> table;
    uint64_t at = aligned(sizeof(AssetHeader) + sections.size() * sizeof(SectionEntry));
    for (const Pending& p : sections) {
        table.push_back({uint32_t(p.type), p.element_size, at, p.size, p.count});
        L.parts.push_back({p.bytes, p.size, at});
        at = aligned(at + p.size);
    }
    L.file_size = at;

    AssetHeader h{};
    std::memcpy(h.magic, asset_magic, 8);
    h.version = asset_version;
    h.header_size = sizeof(AssetHeader);
    h.section_count = uint32_t(sections.size());
    h.file_size = L.file_size;
    L.head.resize(sections.empty() ? L.file_size : table[0].offset, 0);
    std::memcpy(L.head.data(), &h, sizeof h);
    std::memcpy(L.head.data() + sizeof h, table.data(), table.size() * sizeof(SectionEntry));
}

constexpr size_t checksum_at = offsetof(AssetHeader, checksum);

// The file's bytes in order, as pieces, for parts [from, to): the head first when `from` is 0, then each
// part preceded by its zero padding, and the padding at the end when `to` is the last.
template <class Piece>
void each_piece(const AssetLayout& L, size_t from, size_t to, Piece&& piece) {
    static const uint8_t zeros[asset_alignment] = {};
    if (from == 0) piece(L.head.data(), L.head.size(), uint64_t(0));
    uint64_t at = from == 0 ? L.head.size() : L.parts[from - 1].offset + L.parts[from - 1].size;
    for (size_t i = from; i < to; ++i) {
        const AssetLayout::Part& p = L.parts[i];
        if (p.offset > at) piece(zeros, p.offset - at, at);
        piece(p.bytes, p.size, p.offset);
        at = p.offset + p.size;
    }
    if (to == L.parts.size() && L.file_size > at) piece(zeros, L.file_size - at, at);
}

// Adds the pieces of parts [from, to) to the checksum, skipping the checksum field (asset_checksum,
// computed as the file is written).
void sum_pieces(const AssetLayout& L, size_t from, size_t to, AssetChecksum& sum) {
    if (from == 0) {
        sum.add(L.head.data(), checksum_at);
        sum.add(L.head.data() + checksum_at + 8, L.head.size() - checksum_at - 8);
    }
    each_piece(L, from, to, [&](const uint8_t* bytes, uint64_t size, uint64_t offset) {
        if (offset != 0) sum.add(bytes, size_t(size));  // the head is summed above
    });
}

}  // namespace

std::vector<uint8_t> encode_asset(const std::vector<AssetMesh>& meshes, const std::vector<Instance>& instances,
                                  const std::string& source) {
    AssetLayout L;
    lay_out(L, meshes, encode_geometry(meshes), instances, source);
    for (const auto& gather : L.gathers) gather(meshes);
    std::vector<uint8_t> out;
    out.reserve(L.file_size);  // one allocation for the whole file
    each_piece(L, 0, L.parts.size(),
               [&](const uint8_t* bytes, uint64_t size, uint64_t) { out.insert(out.end(), bytes, bytes + size); });
    const uint64_t checksum = asset_checksum(out.data(), out.size());
    std::memcpy(out.data() + checksum_at, &checksum, sizeof checksum);
    return out;
}

namespace {

[[noreturn]] void write_error(const std::string& path, const std::string& why) {
    throw std::runtime_error(path + ": cannot write (" + why + ")");
}

// Writes size bytes at `offset`; false with errno set on failure.
bool write_at(int fd, const uint8_t* bytes, uint64_t size, uint64_t offset) {
    for (uint64_t done = 0; done < size;) {
        const ssize_t n = ::pwrite(fd, bytes + done, size_t(std::min<uint64_t>(size - done, uint64_t(1) << 30)),
                                   off_t(offset + done));
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) return false;
        done += uint64_t(n);
    }
    return true;
}

// The name of this process's temporary for `path`: `path` + ".tmp" + the process id.
std::string temporary_name(const std::string& path) { return path + ".tmp" + std::to_string(getpid()); }

// Whether process `pid` has ended: gone, or a zombie that nobody has reaped yet (a killed bake whose parent
// died with it waits for the init process, which may take its time, while its output is baked again).
bool process_ended(pid_t pid) {
    if (::kill(pid, 0) != 0) return errno == ESRCH;
    std::ifstream stat("/proc/" + std::to_string(pid) + "/stat");
    std::string line;
    if (!std::getline(stat, line)) return false;
    const size_t name_end = line.rfind(')');  // the state follows the command name, which may hold anything
    return name_end != std::string::npos && name_end + 2 < line.size() && line[name_end + 2] == 'Z';
}

}  // namespace

void remove_dead_temporaries(const std::string& path) {
    namespace fs = std::filesystem;
    const fs::path target(path);
    const fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
    const std::string prefix = target.filename().string() + ".tmp";
    std::error_code ec;
    for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
        const std::string name = it->path().filename().string();
        if (name.size() <= prefix.size() || name.compare(0, prefix.size(), prefix) != 0) continue;
        const std::string digits = name.substr(prefix.size());
        if (digits.size() > 9 || digits.find_first_not_of("0123456789") != std::string::npos) continue;
        const pid_t pid = pid_t(std::stol(digits));
        if (pid > 0 && process_ended(pid)) fs::remove(it->path(), ec);
    }
}

void write_file_atomic(const std::string& path, const std::vector<uint8_t>& bytes) {
    write_file_atomic(path, [&](int fd) { return write_at(fd, bytes.data(), bytes.size(), 0); });
}

AtomicFile::AtomicFile(const std::string& path) : path_(path), tmp_(temporary_name(path)) {
    // Only a regular file (or nothing) is replaced: renaming over a device node, a FIFO or a directory
    // would destroy it.
    struct stat st;
    if (::stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode))
        throw std::runtime_error(path + ": not a regular file (a device, FIFO or directory); refusing to replace it");
    remove_dead_temporaries(path);
    const std::filesystem::path target(path);
    const std::string dir = target.has_parent_path() ? target.parent_path().string() : std::string(".");
    // An unnamed file in the output's folder first (O_TMPFILE): killed while writing, the process leaves
    // nothing behind. It gets the temporary's name only for the instant before the rename; a process
    // killed in that instant leaves a temporary that the next write of the same output removes.
    fd_ = ::open(dir.c_str(), O_TMPFILE | O_WRONLY | O_CLOEXEC, 0666);
    unnamed_ = fd_ >= 0;
    if (!unnamed_) {  // a filesystem without O_TMPFILE: a named temporary from the start
        fd_ = ::open(tmp_.c_str(), O_CREAT | O_TRUNC | O_WRONLY | O_CLOEXEC, 0666);
        if (fd_ < 0) write_error(path, std::strerror(errno));
    }
}

AtomicFile::~AtomicFile() {
    if (fd_ >= 0) ::close(fd_);
    if (!committed_) ::unlink(tmp_.c_str());
}

void AtomicFile::fail(int err) {
    ::close(fd_);
    fd_ = -1;
    ::unlink(tmp_.c_str());
    write_error(path_, std::strerror(err ? err : EIO));
}

void AtomicFile::commit() {
    int err = 0;
    bool ok = true;
    if (unnamed_) {
        const std::string self = "/proc/self/fd/" + std::to_string(fd_);
        ok = ::linkat(AT_FDCWD, self.c_str(), AT_FDCWD, tmp_.c_str(), AT_SYMLINK_FOLLOW) == 0;
        if (!ok) err = errno;
    }
    const int closing = ::close(fd_);
    fd_ = -1;
    if (closing != 0 && ok) {
        ok = false;
        err = errno;
    }
    if (ok && std::rename(tmp_.c_str(), path_.c_str()) != 0) {
        ok = false;
        err = errno;
    }
    if (!ok) {
        ::unlink(tmp_.c_str());
        write_error(path_, std::strerror(err ? err : EIO));
    }
    committed_ = true;
}

void write_file_atomic(const std::string& path, const std::function<bool(int)>& fill) {
    AtomicFile file(path);
    if (!fill(file.fd())) file.fail(errno);
    file.commit();
}

}  // namespace cb

namespace cb {

std::vector<EncodedMesh> encode_geometry(const std::vector<AssetMesh>& meshes) {
    std::vector<EncodedMesh> out;
    for (const AssetMesh& m : meshes) out.push_back(encode_mesh(m));
    return out;
}

namespace {

// A large file written front to back with direct writes (O_DIRECT) from one aligned buffer: its bytes go
// from the buffer to the device without a page-cache copy. On a virtual machine whose free memory goes back
// to its host, each fresh page-cache page costs microseconds when first written, and copying a 158 MB asset
// into them took 0.29 s of CPU in a two-thread bake of 10 M triangles (docs/PERFORMANCE.md). Blocks are
// 4 KB (a multiple of any common device block); the padding of the last one is cut off at the end, and the
// checksum is patched into the first block, kept for it, once known.
class DirectStream {
public:
    static constexpr size_t block = 4096, capacity = size_t(4) << 20;

    // A stream on `fd`, or none when its filesystem takes no direct writes.
    static std::unique_ptr<DirectStream> open(int fd) {
        const int flags = ::fcntl(fd, F_GETFL);
        if (flags < 0 || ::fcntl(fd, F_SETFL, flags | O_DIRECT) != 0) return nullptr;
        return std::unique_ptr<DirectStream>(new DirectStream(fd));
    }
    ~DirectStream() { std::free(buffer_); }

    // Appends the file's next `size` bytes; false with errno set when a write fails.
    bool add(const uint8_t* bytes, uint64_t size) {
        while (size > 0) {
            const size_t take = size_t(std::min<uint64_t>(size, capacity - filled_));
            std::memcpy(buffer_ + filled_, bytes, take);
            filled_ += take;
            bytes += take;
            size -= take;
            if (filled_ == capacity && !flush(capacity)) return false;
        }
        return true;
    }

    // Writes what is left, cuts the file to `file_size` and writes `checksum` at `checksum_offset` (in the
    // first block).
    bool finish(uint64_t file_size, uint64_t checksum, size_t checksum_offset) {
        const size_t whole = (filled_ + block - 1) / block * block;
        std::memset(buffer_ + filled_, 0, whole - filled_);
        filled_ = whole;
        if (!flush(whole)) return false;
        if (base_ > file_size && ::ftruncate(fd_, off_t(file_size)) != 0) return false;
        std::memcpy(first_ + checksum_offset, &checksum, sizeof checksum);
        return write_blocks(first_, block, 0);
    }

private:
    explicit DirectStream(int fd) : fd_(fd) {
        if (posix_memalign(reinterpret_cast<void**>(&buffer_), block, capacity + block) != 0) throw std::bad_alloc();
        first_ = buffer_ + capacity;
    }

    // Writes the buffer's first `bytes` (whole blocks) at base_ and keeps what follows them.
    bool flush(size_t bytes) {
        if (!write_blocks(buffer_, bytes, base_)) return false;
        if (base_ == 0) std::memcpy(first_, buffer_, block);
        filled_ -= bytes;
        std::memmove(buffer_, buffer_ + bytes, filled_);
        base_ += bytes;
        return true;
    }

    bool write_blocks(const uint8_t* bytes, size_t size, uint64_t offset) {
        for (size_t done = 0; done < size;) {
            const ssize_t n = ::pwrite(fd_, bytes + done, size - done, off_t(offset + done));
            if (n < 0 && errno == EINTR) continue;
            // A device whose blocks are larger than ours, or a short write that left the rest unaligned: the
            // same bytes through the page cache.
            if (n < 0 && errno == EINVAL && !buffered_) {
                const int flags = ::fcntl(fd_, F_GETFL);
                if (flags < 0 || ::fcntl(fd_, F_SETFL, flags & ~O_DIRECT) != 0) return false;
                buffered_ = true;
                continue;
            }
            if (n <= 0) return false;
            done += size_t(n);
        }
        return true;
    }

    int fd_;
    bool buffered_ = false;
    uint8_t* buffer_ = nullptr;  // capacity bytes, then first_
    uint8_t* first_ = nullptr;   // the file's first block, as written
    uint64_t base_ = 0;          // the file offset of buffer_[0], a multiple of block
    size_t filled_ = 0;
};

// Files from this size on are written by a DirectStream where the filesystem allows. Smaller ones take the
// page cache: their copies cost little, while every direct write waits on the device (the 16 MB asset of
// 1 M triangles bakes in the same time either way).
constexpr uint64_t direct_from_bytes = uint64_t(8) << 20;

}  // namespace

struct AssetWriter::State {
    AssetLayout L;
    AtomicFile file;
    AssetChecksum sum;
    std::string source;                    // the source section's bytes, written by finish()
    std::unique_ptr<DirectStream> stream;  // for a large file, where the filesystem takes direct writes
    State(const std::string& path, const std::string& source) : file(path), source(source) {}

    // Writes the pieces of parts [from, to) at their offsets and adds them to the checksum: the writing on
    // a second thread while this one sums, when `threads` allows (the checksum, serial by its definition,
    // then costs no time of its own).
    void write_parts(size_t from, size_t to, unsigned threads) {
        std::atomic<bool> written{true};
        std::atomic<int> error{0};
        auto write_pieces = [&] {
            each_piece(L, from, to, [&](const uint8_t* bytes, uint64_t size, uint64_t offset) {
                if (written && !(stream ? stream->add(bytes, size) : write_at(file.fd(), bytes, size, offset))) {
                    error = errno;
                    written = false;
                }
            });
        };
        if ((threads ? threads : std::thread::hardware_concurrency()) > 1) {
            std::thread writer(write_pieces);
            sum_pieces(L, from, to, sum);
            writer.join();
        } else {
            write_pieces();
            sum_pieces(L, from, to, sum);
        }
        if (!written) file.fail(error);
    }
};

AssetWriter::AssetWriter(const std::string& path, const std::vector<AssetMesh>& meshes,
                         std::vector<EncodedMesh> geometry, const std::vector<Instance>& instances,
                         const std::string& source)
    : state_(std::make_unique<State>(path, source)) {
    AssetLayout& L = state_->L;
    lay_out(L, meshes, std::move(geometry), instances, state_->source);
    if (L.file_size >= direct_from_bytes) state_->stream = DirectStream::open(state_->file.fd());
    // On the thread that calls: beside a fitting that keeps every core busy, a second one would only take
    // turns with it.
    state_->write_parts(0, L.bounds_from, 1);
    free_storage(L.positions);
    free_storage(L.triangles);
    free_storage(L.refs);
    free_storage(L.fine);
    // The rest of the file, as zeros for now: finish() then writes over pages the file already has. Taking
    // fresh pages is most of a write's cost on a virtual machine; here it overlaps the fitting instead of
    // adding to the serial end of the bake.
    if (!state_->stream && L.bounds_from < L.parts.size()) {
        static const std::vector<uint8_t> zeros(size_t(1) << 20, 0);
        for (uint64_t at = L.parts[L.bounds_from].offset; at < L.file_size; at += zeros.size())
            if (!write_at(state_->file.fd(), zeros.data(), std::min<uint64_t>(zeros.size(), L.file_size - at), at))
                state_->file.fail(errno);
    }
}

AssetWriter::~AssetWriter() = default;

uint64_t AssetWriter::finish(std::vector<AssetMesh>& meshes, unsigned threads) {
    AssetLayout& L = state_->L;
    for (const auto& gather : L.gathers) gather(meshes);
    for (AssetMesh& m : meshes) {  // their encoded copies are in the file
        free_storage(m.positions);
        free_storage(m.triangles);
    }
    state_->write_parts(L.bounds_from, L.parts.size(), threads);
    const uint64_t checksum = state_->sum.finish();
    if (state_->stream ? !state_->stream->finish(L.file_size, checksum, checksum_at)
                       : !write_at(state_->file.fd(), reinterpret_cast<const uint8_t*>(&checksum), 8, checksum_at))
        state_->file.fail(errno);
    state_->file.commit();
    return L.file_size;
}

uint64_t write_asset(const std::string& path, std::vector<AssetMesh>& meshes, std::vector<EncodedMesh> geometry,
                     const std::vector<Instance>& instances, const std::string& source, unsigned threads) {
    return AssetWriter(path, meshes, std::move(geometry), instances, source).finish(meshes, threads);
}

}  // namespace cb
