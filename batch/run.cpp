#include "run.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <new>
#include <stdexcept>
#include <string>
#include <type_traits>

#include "asset_writer.h"
#include "core_budget.h"
#include "parallel.h"
#include "timing.h"

namespace cb {
namespace {

// Every field of a result, in one order for writing and reading it: the child's result crosses the pipe
// whole, so that the parent's copy is what bake_file gave.
template <class Result, class Field>
void each_field(Result& r, Field&& field) {
    field(r.status), field(r.error), field(r.warning), field(r.input_bytes), field(r.output_bytes);
    field(r.triangles), field(r.fine_clusters), field(r.coarse_clusters), field(r.meshes), field(r.instances);
    field(r.load_seconds), field(r.write_seconds), field(r.seconds), field(r.stats);
}

std::string encode_result(const BakeResult& r) {
    std::string out;
    each_field(r, [&](const auto& v) {
        using T = std::decay_t<decltype(v)>;
        if constexpr (std::is_same_v<T, std::string>) {
            const uint64_t size = v.size();
            out.append(reinterpret_cast<const char*>(&size), sizeof size);
            out += v;
        } else {
            static_assert(std::is_trivially_copyable_v<T>);
            out.append(reinterpret_cast<const char*>(&v), sizeof v);
        }
    });
    return out;
}

// False when `bytes` are not exactly one result (a child that died while writing it).
bool decode_result(const std::string& bytes, BakeResult& r) {
    size_t at = 0;
    bool ok = true;
    auto take = [&](void* to, size_t size) {
        ok = ok && size <= bytes.size() - at;
        if (ok) {
            std::memcpy(to, bytes.data() + at, size);
            at += size;
        }
    };
    each_field(r, [&](auto& v) {
        using T = std::decay_t<decltype(v)>;
        if constexpr (std::is_same_v<T, std::string>) {
            uint64_t size = 0;
            take(&size, sizeof size);
            ok = ok && size <= bytes.size() - at;
            if (ok) v.assign(bytes, at, size_t(size)), at += size_t(size);
        } else {
            take(&v, sizeof v);
        }
    });
    return ok && at == bytes.size();
}

bool write_all(int fd, const std::string& bytes) {
    for (size_t done = 0; done < bytes.size();) {
        const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) return false;
        done += size_t(n);
    }
    return true;
}

// "killed by signal 11 (SIGSEGV)", "ended with exit code 3": how a child that gave no result ended.
std::string ending_text(int status) {
    if (WIFSIGNALED(status)) {
        const int signal = WTERMSIG(status);
        std::string text = "killed by signal " + std::to_string(signal);
#if defined(__GLIBC__) && (__GLIBC__ > 2 || __GLIBC_MINOR__ >= 32)
        if (const char* name = sigabbrev_np(signal)) text += std::string(" (SIG") + name + ")";
#endif
        return text;
    }
    if (WIFEXITED(status)) return "ended with exit code " + std::to_string(WEXITSTATUS(status));
    return "ended with status " + std::to_string(status);
}

// The number of threads this process runs, from /proc; 1 when it cannot be read.
unsigned thread_count() {
    std::ifstream status("/proc/self/status");
    for (std::string line; std::getline(status, line);)
        if (line.compare(0, 8, "Threads:") == 0) return unsigned(std::strtoul(line.c_str() + 8, nullptr, 10));
    return 1;
}

// The child: bakes request `r` under its memory budget, drawing helper cores from `shared` through a view
// counted in `held`, writes the result to `out`, and ends without running this process's exit handlers or
// flushing its copies of the parent's buffers.
[[noreturn]] void bake_in_child(const BakeRequest& r, int out, CoreBudget& shared, std::atomic<int>& held,
                                pid_t parent) {
    // Killed with the batch: a batch stopped (even by SIGKILL) leaves no bake running behind it.
    ::prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (::getppid() != parent) ::_exit(1);
    CoreBudget view(shared, held);
    thread_core_budget() = &view;
    limit_process_memory(r.load.memory_budget, r.threads);
    int code = 0;
    try {
        if (!write_all(out, encode_result(bake_file(r)))) code = 3;
    } catch (...) {  // bake_file does not throw; its result's bytes may find no memory
        code = 4;
    }
    ::_exit(code);
}

// Memory shared with the children, made before the first fork: the core budget, then each slot's count of
// the cores its child holds.
class SharedCores {
public:
    SharedCores(unsigned cores, unsigned slots) : size_(sizeof(CoreBudget) + slots * sizeof(std::atomic<int>)) {
        memory_ = ::mmap(nullptr, size_, PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0);
        if (memory_ == MAP_FAILED)
            throw std::runtime_error(std::string("batch: cannot share the cores between processes (") +
                                     std::strerror(errno) + ")");
        budget_ = new (memory_) CoreBudget(cores);
        held_ = reinterpret_cast<std::atomic<int>*>(static_cast<char*>(memory_) + sizeof(CoreBudget));
        for (unsigned s = 0; s < slots; ++s) new (held_ + s) std::atomic<int>(0);
    }
    ~SharedCores() { ::munmap(memory_, size_); }
    SharedCores(const SharedCores&) = delete;
    SharedCores& operator=(const SharedCores&) = delete;

    CoreBudget& budget() { return *budget_; }
    std::atomic<int>& held(unsigned slot) { return held_[slot]; }

private:
    size_t size_;
    void* memory_;
    CoreBudget* budget_;
    std::atomic<int>* held_;
};
static_assert(sizeof(CoreBudget) % alignof(std::atomic<int>) == 0);

}  // namespace

std::vector<BakeResult> run_batch(const std::vector<BakeRequest>& requests, const std::vector<size_t>& order,
                                  const BatchRun& run, const std::function<void(size_t)>& started,
                                  const std::function<void(size_t, const BakeResult&)>& finished) {
    std::vector<BakeResult> results(requests.size());
    if (order.empty()) return results;
    // A thread just joined may still be counted for a moment while the kernel releases it.
    for (int wait = 0; wait < 100 && thread_count() > 1; ++wait) ::usleep(1000);
    if (thread_count() > 1) throw std::logic_error("run_batch: the calling process runs other threads; it must not");
    // Children ignored (SIGCHLD set to SIG_IGN, which a program inherits) are reaped by the kernel, and
    // waitpid would then never tell how one ended.
    struct sigaction child_signal {};
    if (::sigaction(SIGCHLD, nullptr, &child_signal) == 0 && child_signal.sa_handler == SIG_IGN)
        ::signal(SIGCHLD, SIG_DFL);
    const unsigned cores = threads_or_all(run.cores);
    const unsigned slots = unsigned(std::min<size_t>(run.jobs ? run.jobs : cores, order.size()));
    SharedCores shared(cores, slots);
    CoreBudget& budget = shared.budget();
    const pid_t self = ::getpid();

    struct Child {
        pid_t pid = 0;  // 0: the slot is free
        int fd = -1;    // the read end of the child's result pipe
        size_t request = 0;
        std::string bytes;
        std::chrono::steady_clock::time_point start;
    };
    std::vector<Child> children(slots);
    size_t next = 0;

    auto finish = [&](size_t i, const BakeResult& r) {
        results[i] = r;
        if (finished) finished(i, results[i]);
    };
    // Forks a child for request i in slot s; the one-line reason it could not, or empty.
    auto fork_child = [&](size_t i, unsigned s) -> std::string {
        int pipe_fds[2];
        if (::pipe2(pipe_fds, O_CLOEXEC) != 0) return std::strerror(errno);
        std::fflush(nullptr);
        shared.held(s) = 0;
        const pid_t pid = ::fork();
        if (pid < 0) {
            const int error = errno;
            ::close(pipe_fds[0]);
            ::close(pipe_fds[1]);
            return std::strerror(error);
        }
        if (pid == 0) {
            ::close(pipe_fds[0]);
            for (const Child& c : children)
                if (c.pid) ::close(c.fd);
            bake_in_child(requests[i], pipe_fds[1], budget, shared.held(s), self);
        }
        ::close(pipe_fds[1]);
        children[s] = Child{pid, pipe_fds[0], i, {}, std::chrono::steady_clock::now()};
        return {};
    };
    // Starts the next request in slot s, which holds its core: false when none is left to start.
    auto launch = [&](unsigned s) {
        while (next < order.size()) {
            const size_t i = order[next++];
            if (started) started(i);
            const std::string error = fork_child(i, s);
            if (error.empty()) return true;
            BakeResult r;
            r.error = LoadError::printable(requests[i].input + ": cannot start a process to bake it (" + error + ")");
            finish(i, r);
        }
        return false;
    };
    // The child of slot s has closed its pipe: reaps it, reports its file, and starts the next in its slot.
    auto reap = [&](unsigned s) {
        Child& c = children[s];
        ::close(c.fd);
        int status = 0;
        while (::waitpid(c.pid, &status, 0) < 0 && errno == EINTR) {}
        budget.reclaim(shared.held(s));
        const BakeRequest& request = requests[c.request];
        BakeResult r;
        if (!(WIFEXITED(status) && WEXITSTATUS(status) == 0 && decode_result(c.bytes, r))) {
            r = BakeResult{};
            r.error = LoadError::printable(request.input + ": the bake was " + ending_text(status));
            r.seconds = seconds_since(c.start);
            remove_dead_temporaries(request.output);  // one it named in the instant before its rename
        }
        c.pid = 0;
        c.bytes.clear();
        finish(c.request, r);
        if (!launch(s)) budget.give();
    };

    // A slot holds its core from its first file to its last, so that no other file's parallel stage takes
    // it in between and finds three threads on two cores.
    for (unsigned s = 0; s < slots && next < order.size(); ++s) {
        budget.take();
        if (!launch(s)) budget.give();
    }
    std::vector<pollfd> polled;
    std::vector<unsigned> polled_slot;
    char buffer[1 << 16];
    while (true) {
        polled.clear();
        polled_slot.clear();
        for (unsigned s = 0; s < slots; ++s)
            if (children[s].pid) {
                polled.push_back({children[s].fd, POLLIN, 0});
                polled_slot.push_back(s);
            }
        if (polled.empty()) break;
        if (::poll(polled.data(), polled.size(), -1) < 0) {
            if (errno == EINTR) continue;
            throw std::runtime_error(std::string("batch: cannot wait for the bakes (") + std::strerror(errno) + ")");
        }
        for (size_t k = 0; k < polled.size(); ++k) {
            if (!polled[k].revents) continue;
            Child& c = children[polled_slot[k]];
            const ssize_t n = ::read(c.fd, buffer, sizeof buffer);
            if (n > 0)
                c.bytes.append(buffer, size_t(n));
            else if (n == 0 || errno != EINTR)
                reap(polled_slot[k]);
        }
    }
    return results;
}

}  // namespace cb
