#include "sim/run.h"

#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fmt/format.h>
#include <CLI/CLI.hpp>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <systemc>
#include <thread>
#include <utility>

#include "models/traversal_mode.h"
#include "sim/chip.h"
#include "sim/config.h"
#include "sim/errors.h"
#include "sim/stats_report.h"
#include "workloads/bvh.h"
#include "workloads/error.h"
#include "workloads/output_file.h"
#include "workloads/packet.h"
#include "workloads/raygen.h"
#include "workloads/scene.h"
#include "workloads/trace_file.h"
#include "workloads/tracer.h"

namespace rtsim {

namespace fs = std::filesystem;
using nlohmann::json;
using Clock = std::chrono::steady_clock;

void parse_resolution(const std::string& text, const std::string& what, int& width, int& height) {
    int w = 0, h = 0;
    char x = 0, extra = 0;
    if (std::sscanf(text.c_str(), "%d%c%d%c", &w, &x, &h, &extra) != 3 || (x != 'x' && x != 'X') ||
        w <= 0 || h <= 0 || w > 65536 || h > 65536)
        throw InputError(
            fmt::format("{}: expected WIDTHxHEIGHT with each in 1..65536, got '{}'", what, text));
    width = w;
    height = h;
}

Bvh build_bvh_from_config(const Config& cfg, const Scene& scene) {
    BvhLayout layout;
    layout.node_size_bytes = cfg.typed.node_size_bytes;
    layout.tri_size_bytes = cfg.typed.triangle_size_bytes;
    return build_bvh(scene, cfg.typed.bvh, layout);
}

double peak_rss_mib() {
    rusage ru{};
    getrusage(RUSAGE_SELF, &ru);
    return double(ru.ru_maxrss) / 1024.0;  // Linux reports KiB
}

void WorkloadOptions::resolve() {
    parse_resolution(res, "--res", gen.width, gen.height);
    gen.kinds = parse_ray_kinds(rays, "--rays");
    gen.light = parse_light_kind(light, "--light");
    gen.validate();
}

void add_workload_options(CLI::App* cmd, WorkloadOptions& w) {
    cmd->add_option("--scene", w.scene,
                    "Mesh file (OBJ, PLY, OFF, STL, ...) or builtin:NAME (cornell, sphere)")
        ->capture_default_str();
    cmd->add_option("--rays", w.rays,
                    "Comma list of ray kinds: primary, shadow, ao, diffuse, reflection")
        ->capture_default_str();
    cmd->add_option("--res", w.res, "Image resolution WIDTHxHEIGHT")->capture_default_str();
    cmd->add_option("--spp", w.gen.spp, "Primary samples per pixel (jittered when more than 1)")
        ->capture_default_str();
    cmd->add_option("--seed", w.gen.seed, "Seed for sampled rays")->capture_default_str();
    cmd->add_option("--light", w.light, "Light for shadow rays: point or area")
        ->capture_default_str();
    cmd->add_option("--ao-samples", w.gen.ao_samples, "AO rays per primary hit")
        ->capture_default_str();
    cmd->add_option("--ao-length", w.gen.ao_length_fraction,
                    "AO ray length as a fraction of the scene diagonal")
        ->capture_default_str();
    cmd->add_option("--diffuse-depth", w.gen.diffuse_depth, "Diffuse bounces per primary hit")
        ->capture_default_str();
}

namespace {

// The chip's shared work queue. Counts what it hands out and shows progress on a terminal;
// subclasses produce the rays.
class CountingSource : public RayWorkSource {
  public:
    explicit CountingSource(bool progress) : progress_(progress) {}

    bool next(RayWork& work) override {
        uint32_t hit = 0;
        const bool more = failed() ? false : produce(work, hit);
        if (!more) return false;
        rays_by_kind[static_cast<int>(work.kind)] += work.rays;
        hits_by_kind[static_cast<int>(work.kind)] += hit;
        steps += work.steps.size();
        return true;
    }

    void finish_progress() {
        if (progress_ && printed_) std::fprintf(stderr, "\r%70s\r", "");
    }

    std::array<uint64_t, kRayKindCount> rays_by_kind{}, hits_by_kind{};
    uint64_t steps = 0;
    double functional_seconds = 0;  // time the simulation waited for rays to be produced
                                    // (subclasses measure it where they block)
    // Bad input found mid-run (a damaged trace chunk) stops the simulation; run_command reports
    // it after the kernel returns, without throwing (exceptions must not cross SystemC's
    // coroutine stacks, which AddressSanitizer cannot follow either).
    std::string failure;
    bool failure_is_input = false;
    bool failed() const { return !failure.empty(); }

  protected:
    // Fills the next work item (a ray, or a packet of work.rays rays); `hits`: how many hit.
    virtual bool produce(RayWork& work, uint32_t& hits) = 0;

    void report_progress(double fraction, const char* what) {
        if (!progress_) return;
        const auto now = Clock::now();
        if (printed_ && now - last_print_ < std::chrono::milliseconds(250)) return;
        last_print_ = now;
        printed_ = true;
        uint64_t rays = 0;
        for (uint64_t r : rays_by_kind) rays += r;
        std::fprintf(stderr, "\r[rtsim] %5.1f%% of %s, %llu rays, %.4g simulated us   ",
                     100.0 * fraction, what, (unsigned long long)rays,
                     sc_core::sc_time_stamp().to_seconds() * 1e6);
        std::fflush(stderr);
    }

  private:
    bool progress_, printed_ = false;
    Clock::time_point last_print_;
};

// Work prepared on a helper thread, one batch ahead of the simulation: the simulation never
// waits for ray generation, tracing or trace decoding while a second host core is free, and
// errors (a damaged trace chunk) surface on that thread, never inside a SystemC process (whose
// coroutine stacks exceptions must not cross, and which AddressSanitizer cannot follow).
class PrefetchingSource : public CountingSource {
  public:
    PrefetchingSource(bool progress, const char* unit) : CountingSource(progress), unit_(unit) {}
    // Derived destructors stop the helper first (see prefetch); this only makes sure no thread
    // is left joinable.
    ~PrefetchingSource() override { stop_helper(); }

  protected:
    struct Batch {
        std::vector<TraceRecord> records;
        // Packet mode: per record (a packet), its rays and how many of them hit.
        std::vector<uint8_t> packet_rays;
        std::vector<uint32_t> packet_hits;
        double progress = 0;  // fraction of the work done once this batch is used
        bool last = false;    // nothing follows
        std::string error;
        bool input_error = false;
    };
    // Fills the next batch, on the helper thread. It starts with the records of a used batch
    // (their contents are stale; only their memory is worth keeping).
    virtual void fill(Batch& batch) = 0;

    // Derived constructors start the first batch; derived destructors call stop_helper() first, so
    // fill() never runs on a half-destroyed object.
    // `used`: the batch just consumed. Its records (holding the step vectors the ray slots gave
    // back) start the next batch, so a fill may reuse their memory instead of allocating per
    // ray; whatever it does not reuse is freed on the helper thread, which allocated it (a
    // free on another thread's arena costs the simulation thread a lock).
    // One helper thread serves every batch (batches are small, and a thread per batch cost
    // more than decoding one).
    void prefetch() { prefetch(Batch{}); }
    void prefetch(Batch used) {
        std::lock_guard<std::mutex> lock(mutex_);
        if (!helper_.joinable()) helper_ = std::thread([this] { help(); });
        recycled_ = std::move(used);
        requested_ = true;
        outstanding_ = true;
        cv_.notify_all();
    }
    // Stops the helper thread once it has finished the batch it may be filling.
    void stop_helper() {
        {
            std::lock_guard<std::mutex> lock(mutex_);
            stopping_ = true;
            cv_.notify_all();
        }
        if (helper_.joinable()) helper_.join();
    }

    bool produce(RayWork& work, uint32_t& hits) override {
        while (pos_ == batch_.records.size()) {
            if (!outstanding_) return false;
            const auto t0 = Clock::now();
            Batch used = std::exchange(batch_, take());
            functional_seconds += std::chrono::duration<double>(Clock::now() - t0).count();
            pos_ = 0;
            if (!batch_.error.empty()) {
                failure = batch_.error;
                failure_is_input = batch_.input_error;
                sc_core::sc_stop();
                return false;
            }
            report_progress(batch_.progress, unit_);
            if (!batch_.last) prefetch(std::move(used));
        }
        // The next rays' steps were written on the helper thread: start moving them into this
        // core's caches before a ray slot needs them.
        if (pos_ + kPrefetchAheadRays < batch_.records.size()) {
            const auto& ahead = batch_.records[pos_ + kPrefetchAheadRays].steps;
            const char* p = reinterpret_cast<const char*>(ahead.data());
            for (size_t b = 0; b < ahead.size() * sizeof(Step); b += 64) __builtin_prefetch(p + b);
        }
        TraceRecord& r = batch_.records[pos_++];
        work.ray_id = r.ray_id;
        work.kind = r.kind;
        work.steps.swap(r.steps);
        work.rays = 1;
        hits = r.prim != kInvalidPrim;
        if (pos_ <= batch_.packet_hits.size()) {
            work.rays = batch_.packet_rays[pos_ - 1];
            hits = batch_.packet_hits[pos_ - 1];
        }
        return true;
    }

  private:
    // The helper thread: fills a batch whenever one is requested, until stopped.
    void help() {
        std::unique_lock<std::mutex> lock(mutex_);
        for (;;) {
            cv_.wait(lock, [this] { return requested_ || stopping_; });
            if (stopping_) return;
            requested_ = false;
            Batch used = std::move(recycled_);
            lock.unlock();
            Batch b;
            b.records = std::move(used.records);
            used = Batch();
            try {
                fill(b);
            } catch (const InputError& e) {
                b.error = e.what();
                b.input_error = true;
            } catch (const std::exception& e) {
                b.error = e.what();
            }
            lock.lock();
            filled_ = std::move(b);
            ready_ = true;
            cv_.notify_all();
        }
    }
    // The batch requested last, once the helper has filled it.
    Batch take() {
        std::unique_lock<std::mutex> lock(mutex_);
        cv_.wait(lock, [this] { return ready_; });
        ready_ = false;
        outstanding_ = false;
        return std::move(filled_);
    }

    static constexpr size_t kPrefetchAheadRays = 4;
    const char* unit_;
    Batch batch_;
    size_t pos_ = 0;
    bool outstanding_ = false;  // a batch was requested and not taken yet (simulation thread)
    std::thread helper_;
    std::mutex mutex_;  // guards what follows
    std::condition_variable cv_;
    Batch recycled_, filled_;
    bool requested_ = false, ready_ = false, stopping_ = false;
};

// Rays from the generator, traced a batch of tiles at a time: only about two batches of rays
// hold step streams at any time.
class GeneratedWorkSource : public PrefetchingSource {
  public:
    // packet_size > 0: runs of consecutive rays of one kind are traced as packets of up to
    // that many rays, each packet one work item.
    GeneratedWorkSource(const Bvh& bvh, RayGenerator& gen, bool progress, int packet_size = 0)
        : PrefetchingSource(progress, "tiles"), bvh_(bvh), gen_(gen), packet_size_(packet_size) {
        gen_.set_record_steps(packet_size_ == 0);  // packets trace their own way
        prefetch();
    }
    ~GeneratedWorkSource() override { stop_helper(); }

  protected:
    void fill(Batch& b) override {
        b.records.clear();  // steps are moved in from the tracer: nothing to reuse
        constexpr size_t kBatchRays = 4096;
        std::vector<GeneratedRay> rays;
        bool more = true;
        while (rays.size() < kBatchRays && (more = gen_.next_tile(rays))) ++tiles_done_;
        if (packet_size_ > 0) {
            fill_packets(rays, b);
        } else {
            b.records.resize(rays.size());
            for (size_t i = 0; i < rays.size(); ++i) {
                TraceRecord& r = b.records[i];
                r.ray_id = rays[i].id;
                r.kind = rays[i].kind;
                if (rays[i].traced) {  // the generator traced it already, for its hit
                    r.steps = std::move(rays[i].steps);
                    r.prim = rays[i].prim;
                } else {
                    r.prim = trace_ray(bvh_, rays[i].ray, rays[i].query, &r.steps).prim;
                }
            }
        }
        b.progress = double(tiles_done_) / std::max(1, gen_.tile_count());
        b.last = !more;
    }

  private:
    void fill_packets(const std::vector<GeneratedRay>& rays, Batch& b) {
        Ray packet[kMaxPacketSize];
        Hit hits[kMaxPacketSize];
        PacketOptions po;
        po.size = packet_size_;
        PacketStats ps;
        for (const auto& [i, e] :
             packet_runs(rays.size(), packet_size_, [&](size_t k) { return rays[k].kind; })) {
            const int n = int(e - i);
            for (int k = 0; k < n; ++k) packet[k] = rays[i + size_t(k)].ray;
            TraceRecord r;
            r.ray_id = rays[i].id;
            r.kind = rays[i].kind;
            trace_packet(bvh_, packet, n, rays[i].query, hits, po, ps, &r.steps);
            uint32_t hit_count = 0;
            for (int k = 0; k < n; ++k) hit_count += hits[k].valid();
            b.records.push_back(std::move(r));
            b.packet_rays.push_back(uint8_t(n));
            b.packet_hits.push_back(hit_count);
        }
    }

    const Bvh& bvh_;
    RayGenerator& gen_;
    int packet_size_;
    int tiles_done_ = 0;  // touched by the helper thread only
};

// Rays replayed from a trace file, a chunk at a time.
class TraceWorkSource : public PrefetchingSource {
  public:
    TraceWorkSource(TraceReader& reader, bool progress)
        : PrefetchingSource(progress, "chunks"), reader_(reader) {
        prefetch();
    }
    ~TraceWorkSource() override { stop_helper(); }

  protected:
    void fill(Batch& b) override {
        // A batch is at most kBatchRays of a chunk: its steps (~300 bytes a ray) stay in the
        // host's caches until the cores run them, even with the decoding on the same core.
        constexpr size_t kBatchRays = 1024;
        if (reader_.chunk_rays_left() == 0 && next_chunk_ < reader_.chunk_count())
            reader_.open_chunk(next_chunk_++);
        reader_.read_records(kBatchRays, b.records);
        b.progress = double(next_chunk_) / double(std::max<size_t>(1, reader_.chunk_count()));
        b.last = next_chunk_ == reader_.chunk_count() && reader_.chunk_rays_left() == 0;
    }

  private:
    TraceReader& reader_;
    size_t next_chunk_ = 0;  // touched by the helper thread only
};

std::string fresh_out_dir() {
    const std::time_t now = std::time(nullptr);
    char stamp[32];
    std::strftime(stamp, sizeof stamp, "%Y%m%d-%H%M%S", std::localtime(&now));
    for (int i = 0;; ++i) {
        std::string d = fmt::format("out/run-{}{}", stamp, i ? fmt::format("-{}", i) : "");
        if (!fs::exists(d)) return d;
    }
}

// Per-window figures for plots: bandwidth in GB/s at each level and unit utilisation.
json time_series_report(const Chip& chip, const ReportInputs& ri) {
    const auto& S = chip.series;
    const uint64_t window = S.rays->window_cycles();
    const size_t n = size_t((ri.total_cycles + window - 1) / window);
    const double window_seconds = double(window) / (ri.clock_ghz * 1e9);
    auto values = [&](const TimeSeries& t, double scale) {
        json a = json::array();
        for (size_t w = 0; w < n; ++w)
            a.push_back(w < t.buckets().size() ? double(t.buckets()[w]) * scale : 0.0);
        return a;
    };
    const double gbps = 1.0 / window_seconds / 1e9;
    return {
        {"window_cycles", window},
        {"windows", n},
        {"dram_gbps", values(*S.dram_bytes, gbps)},
        {"l2_to_l1_gbps", values(*S.l1_fill_bytes, gbps)},
        {"dram_to_l2_gbps", values(*S.l2_fill_bytes, gbps)},
        {"box_unit_utilization",
         values(*S.box_busy, 1.0 / (double(window) * ri.box_pipelines_per_core * ri.box_units))},
        {"triangle_unit_utilization",
         values(*S.triangle_busy,
                1.0 / (double(window) * ri.triangle_pipelines_per_core * ri.triangle_units))},
        {"rays", values(*S.rays, 1.0)}};
}

// Runs this command again in a child process with ideal memory and unlimited units (a SystemC
// kernel runs once per process) and returns the child's stats.json.
json run_bound(const RunOptions& opt) {
    std::vector<std::string> args = {"/proc/self/exe"};
    for (size_t i = 1; i < opt.argv.size(); ++i) {
        const std::string& a = opt.argv[i];
        if (a == "--bound" || a == "--quiet" || a == "-q") continue;
        if (a == "--out" || a == "-o") {
            ++i;  // and its value
            continue;
        }
        if (a.rfind("--out=", 0) == 0) continue;
        args.push_back(a);
    }
    char tmpl[] = "/tmp/rtsim-bound-XXXXXX";
    const char* dir = mkdtemp(tmpl);
    if (!dir) throw std::runtime_error("--bound: cannot create a temporary folder");
    for (const char* extra :
         {"--set", "sim.ideal_memory=true", "--set", "sim.ideal_units=true", "--quiet", "--out"})
        args.push_back(extra);
    args.push_back(dir);
    std::vector<char*> cargv;
    for (std::string& a : args) cargv.push_back(a.data());
    cargv.push_back(nullptr);
    pid_t pid;
    if (posix_spawn(&pid, cargv[0], nullptr, nullptr, cargv.data(), environ) != 0)
        throw std::runtime_error("--bound: cannot start the ideal run");
    int status = 0;
    waitpid(pid, &status, 0);
    const std::string path = (fs::path(dir) / "stats.json").string();
    std::ifstream in(path);
    json b = json::parse(in, nullptr, false);
    std::error_code ec;
    fs::remove_all(dir, ec);
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0 || b.is_discarded())
        throw std::runtime_error("--bound: the ideal run failed");
    return b;
}

json aabb_json(const AABB& b) {
    return {{"lo", {b.lo.x, b.lo.y, b.lo.z}}, {"hi", {b.hi.x, b.hi.y, b.hi.z}}};
}

}  // namespace

json scene_summary(const Scene& scene) {
    return {{"name", scene.name},
            {"source", scene.source},
            {"triangles", scene.triangle_count()},
            {"vertices", scene.vertices.size()},
            {"hash", fmt::format("{:016x}", scene.content_hash())},
            {"bounds", aabb_json(scene.bounds())}};
}

json bvh_summary(const Bvh& bvh, bool treelet_tables) {
    const BvhQuality& q = bvh.quality;
    const BvhBuildOptions& bo = bvh.options;
    const BvhLayout& L = bvh.layout;
    json out = {{"builder", bvh_builder_name(bo.builder)},
                {"restructure_passes", bo.restructure_passes},
                {"width", bvh.width()},
                {"node_format", node_format_name(bo.node_format)},
                {"sah_cost", q.sah_cost},
                {"sah_traversal_cost", bo.traversal_cost},
                {"sah_intersection_cost", bo.intersection_cost},
                {"nodes", q.node_count},
                {"inner_nodes", q.inner_count},
                {"leaves", q.leaf_count},
                {"max_depth", q.max_depth},
                {"mean_leaf_size", q.mean_leaf_size},
                {"mean_children", q.mean_children},
                {"bytes", q.bytes},
                {"layout",
                 {{"node_base_addr", L.node_base_addr},
                  {"node_size_bytes", L.node_size_bytes},
                  {"inner_node_count", L.inner_node_count},
                  {"triangle_base_addr", L.tri_base_addr},
                  {"triangle_size_bytes", L.tri_size_bytes},
                  {"triangle_count", L.triangle_count},
                  {"treelet_bytes", L.treelet_bytes},
                  {"treelets", L.treelet_bytes ? L.treelet_count() : 0}}}};
    // Stats keep the figures, traces also the tables (a replay needs them to know treelets).
    if (treelet_tables) {
        out["layout"]["treelet_node_start"] = L.treelet_node_start;
        out["layout"]["treelet_tri_start"] = L.treelet_tri_start;
    }
    return out;
}

json workload_summary(const RayGenOptions& rg, float ao_length) {
    return {{"rays", ray_kinds_to_string(rg.kinds)},
            {"resolution", fmt::format("{}x{}", rg.width, rg.height)},
            {"seed", rg.seed},
            {"spp", rg.spp},
            {"light", light_kind_name(rg.light)},
            {"diffuse_depth", rg.diffuse_depth},
            {"ao_samples", rg.ao_samples},
            {"ao_length_fraction", rg.ao_length_fraction},
            {"ao_length", ao_length},
            {"tile_size", rg.tile_size}};
}

BvhLayout layout_from_summary(const json& bvh, const std::string& where) {
    try {
        const json& l = bvh.at("layout");
        BvhLayout L;
        L.node_base_addr = l.at("node_base_addr").get<uint64_t>();
        L.node_size_bytes = l.at("node_size_bytes").get<uint32_t>();
        L.inner_node_count = l.at("inner_node_count").get<uint32_t>();
        L.tri_base_addr = l.at("triangle_base_addr").get<uint64_t>();
        L.tri_size_bytes = l.at("triangle_size_bytes").get<uint32_t>();
        L.triangle_count = l.at("triangle_count").get<uint32_t>();
        // Traces from before treelets carry no treelet fields: a layout without treelets.
        L.treelet_bytes = l.value("treelet_bytes", 0u);
        L.treelet_node_start = l.value("treelet_node_start", std::vector<uint32_t>());
        L.treelet_tri_start = l.value("treelet_tri_start", std::vector<uint32_t>());
        if (!L.index_treelets() || (L.treelet_bytes == 0) != L.treelet_node_start.empty())
            throw InputError(fmt::format(
                "{}: header metadata bvh.layout has treelet tables that do not cover its {} "
                "nodes and {} triangles",
                where, L.inner_node_count, L.triangle_count));
        return L;
    } catch (const json::exception& e) {
        throw InputError(
            fmt::format("{}: header metadata has no valid bvh.layout ({})", where, e.what()));
    }
}

json open_trace_metadata(TraceReader& reader, const std::string& path) {
    json meta = json::parse(reader.metadata_json(), nullptr, false);
    if (meta.is_discarded() || !meta.is_object() || !meta.contains("bvh") ||
        !meta.contains("scene"))
        throw InputError(
            fmt::format("{}: header metadata is not the JSON an RTSim trace carries", path));
    reader.set_layout(layout_from_summary(meta["bvh"], path));
    return meta;
}

void check_config_combination(const Config& cfg, const std::string& trace_path) {
    const TraversalModeEntry& mode = TraversalModeRegistry::at(cfg.typed.traversal.mode);
    if (!mode.replays_traces && !trace_path.empty())
        throw InputError(
            fmt::format("{}: a trace records single-ray traversal; traversal.mode={} needs rays "
                        "generated on the fly (drop --trace)",
                        trace_path, mode.name));
}

void check_trace_matches_config(const json& bvh, const Config& cfg, const std::string& where) {
    auto refuse = [&](const std::string& field, const std::string& recorded,
                      const std::string& wanted) {
        throw InputError(fmt::format(
            "{}: recorded with {}={}, but the config asks for {}; record the trace again "
            "or use a config with the same BVH layout",
            where, field, recorded, wanted));
    };
    const Params& P = cfg.typed;
    const int width = bvh.value("width", 0);
    if (width != P.bvh.width)
        refuse("bvh.width", std::to_string(width), std::to_string(P.bvh.width));
    const std::string format = bvh.value("node_format", std::string("?"));
    if (format != node_format_name(P.bvh.node_format))
        refuse("bvh.node_format", format, node_format_name(P.bvh.node_format));
    const BvhLayout L = layout_from_summary(bvh, where);
    if (P.node_size_bytes != 0 && P.node_size_bytes != L.node_size_bytes)
        refuse("bvh.node_size_bytes", std::to_string(L.node_size_bytes),
               std::to_string(P.node_size_bytes));
    if (P.triangle_size_bytes != L.tri_size_bytes)
        refuse("bvh.triangle_size_bytes", std::to_string(L.tri_size_bytes),
               std::to_string(P.triangle_size_bytes));
    if (P.bvh.treelet_bytes != L.treelet_bytes)
        refuse("bvh.treelet_bytes", std::to_string(L.treelet_bytes),
               std::to_string(P.bvh.treelet_bytes));
}

int run_command(const RunOptions& opt) {
    const auto host_start = Clock::now();
    const Config cfg = load_config(opt.config_path, opt.sets);

    const RayGenOptions& rg = opt.workload.gen;
    // Checked before the long work, so a bad --out fails fast and nothing is half-written.
    const std::string out_dir = opt.out_dir.empty() ? fresh_out_dir() : opt.out_dir;
    std::error_code ec;
    fs::create_directories(out_dir, ec);
    if (ec || !fs::is_directory(out_dir))
        throw InputError(
            fmt::format("--out {}: cannot create output folder: {}", out_dir, ec.message()));

    check_config_combination(cfg, opt.trace_path);
    const bool progress = !opt.quiet && isatty(STDERR_FILENO);
    const auto t_prepare = Clock::now();
    json meta;  // scene, bvh and workload sections of stats.json
    std::unique_ptr<Scene> scene;
    std::unique_ptr<Bvh> bvh;
    std::unique_ptr<RayGenerator> gen;
    std::unique_ptr<TraceReader> reader;
    std::unique_ptr<CountingSource> source_ptr;
    if (opt.trace_path.empty()) {
        scene = std::make_unique<Scene>(load_scene(opt.workload.scene));
        bvh = std::make_unique<Bvh>(build_bvh_from_config(cfg, *scene));
        gen = std::make_unique<RayGenerator>(*scene, *bvh, rg);
        meta = {{"scene", scene_summary(*scene)},
                {"bvh", bvh_summary(*bvh)},
                {"workload", workload_summary(rg, gen->ao_length())}};
        source_ptr = std::make_unique<GeneratedWorkSource>(
            *bvh, *gen, progress,
            TraversalModeRegistry::at(cfg.typed.traversal.mode).packets
                ? cfg.typed.traversal.packet_size
                : 0);
    } else {
        reader = std::make_unique<TraceReader>(opt.trace_path);
        meta = open_trace_metadata(*reader, opt.trace_path);
        check_trace_matches_config(meta["bvh"], cfg, opt.trace_path);
        source_ptr = std::make_unique<TraceWorkSource>(*reader, progress);
    }
    const double prepare_seconds = std::chrono::duration<double>(Clock::now() - t_prepare).count();
    CountingSource& source = *source_ptr;

    Chip chip(cfg.typed, &source, bvh ? bvh->layout : reader->layout());
    const auto t_sim = Clock::now();
    // A run stopped by bad input mid-way reports its own one-line error; the kernel's note that
    // sc_stop() was called would only add noise on stdout.
    sc_core::sc_report_handler::set_actions("/OSCI/SystemC", sc_core::SC_INFO,
                                            sc_core::SC_DO_NOTHING);
    sc_core::sc_start();
    const double sim_seconds = std::chrono::duration<double>(Clock::now() - t_sim).count();
    source.finish_progress();
    if (source.failed()) return report_failure(source.failure, source.failure_is_input);
    if (chip.total_cycles() >= kCalendarCycleLimit)
        return report_failure(fmt::format("simulated time reached {} cycles, past the {} cycles "
                                          "the timing models can count",
                                          chip.total_cycles(), kCalendarCycleLimit),
                              false);

    ReportInputs ri;
    ri.stats = &chip.stats;
    ri.total_cycles = chip.total_cycles();
    ri.clock_ghz = cfg.typed.clock_ghz;
    ri.cores = cfg.typed.core_count;
    ri.box_pipelines_per_core = cfg.typed.box_unit.count;
    ri.triangle_pipelines_per_core = cfg.typed.triangle_unit.count;
    ri.ray_slots_per_core = cfg.typed.core.ray_slots;
    ri.box_units = int(chip.box_units.size());
    ri.triangle_units = int(chip.triangle_units.size());
    ri.dram_channels = cfg.typed.dram.channels;
    ri.ray_bytes = cfg.typed.ray_buffer.ray_bytes;
    ri.ray_capacity = cfg.typed.ray_buffer.capacity_rays;
    for (uint64_t r : source.rays_by_kind) ri.rays += r;
    json timing = timing_report(ri);

    // Ray kinds reported: those the workload asked for (or, for rays from a file, those seen).
    std::array<bool, kRayKindCount> listed{};
    const std::string kinds_text = meta["workload"].value("rays", std::string());
    if (!kinds_text.empty()) listed = parse_ray_kinds(kinds_text, "workload.rays");
    uint64_t total_rays = 0;
    json rays = json::object(), hits = json::object();
    for (int k = 0; k < kRayKindCount; ++k) {
        if (!listed[k] && source.rays_by_kind[k] == 0) continue;
        rays[ray_kind_name(RayKind(k))] = source.rays_by_kind[k];
        hits[ray_kind_name(RayKind(k))] = source.hits_by_kind[k];
        total_rays += source.rays_by_kind[k];
    }
    const double sim_s = timing["simulated_seconds"].get<double>();
    // Host time split: the cores' scheduler running (models, and waiting for rays:
    // functional_s), the rest is the SystemC kernel.
    const double cores_busy = chip.scheduler->host_busy_seconds();
    const double host_total = std::chrono::duration<double>(Clock::now() - host_start).count();

    json out;
    out["rtsim_version"] = RTSIM_VERSION;
    out["config"] = cfg.values;
    out["config_hash"] = cfg.hash();
    out["config_files"] = cfg.files;
    out["config_overrides"] = cfg.overrides;
    for (const char* k : {"scene", "bvh", "workload"}) out[k] = meta[k];
    if (out["bvh"].contains("layout"))  // a trace's treelet tables stay in the trace
        for (const char* k : {"treelet_node_start", "treelet_tri_start"})
            out["bvh"]["layout"].erase(k);
    out["rays"] = {
        {"total", total_rays}, {"by_kind", rays}, {"hits_by_kind", hits}, {"steps", source.steps}};
    out["total_cycles"] = timing["total_cycles"];
    out["clock_ghz"] = ri.clock_ghz;
    out["simulated_seconds"] = sim_s;
    out["rays_per_second"] = sim_s > 0 ? double(total_rays) / sim_s : 0.0;
    for (const char* k : {"units", "caches", "bandwidth", "stalls", "counters"}) out[k] = timing[k];
    out["traversal_mode"] = cfg.typed.traversal.mode;
    for (const char* k : {"ray_buffer", "packets"})
        if (timing.contains(k)) out[k] = timing[k];
    if (chip.series.rays) out["time_series"] = time_series_report(chip, ri);
    // Host timings live apart: everything outside "host" is identical for identical inputs.
    out["host"] = {{"run_time_s", host_total},
                   {"prepare_s", prepare_seconds},
                   {"simulation_s", sim_seconds},
                   {"functional_s", source.functional_seconds},
                   {"simulated_rays_per_host_second",
                    sim_seconds > 0 ? double(total_rays) / sim_seconds : 0.0},
                   {"models_s", std::max(0.0, cores_busy - source.functional_seconds)},
                   {"kernel_s", std::max(0.0, sim_seconds - cores_busy)},
                   {"peak_rss_mib", peak_rss_mib()}};
    if (bvh) out["host"]["bvh_build_s"] = bvh->quality.build_seconds;
    if (reader) out["host"]["trace"] = opt.trace_path;

    if (opt.bound) {
        const json b = run_bound(opt);
        const double bound_rps = b["rays_per_second"].get<double>();
        out["bound"] = {{"sim", {{"ideal_memory", true}, {"ideal_units", true}}},
                        {"total_cycles", b["total_cycles"]},
                        {"rays_per_second", bound_rps},
                        {"achieved_over_bound",
                         bound_rps > 0 ? out["rays_per_second"].get<double>() / bound_rps : 0.0}};
    }

    const std::string stats_path = (fs::path(out_dir) / "stats.json").string();
    write_file_atomically(stats_path, out.dump(2) + "\n");

    if (!opt.quiet) {
        const json& bw = out["bandwidth"];
        const json& un = out["units"];
        const json& ca = out["caches"];
        std::string kinds;
        for (auto& [k, v] : rays.items())
            kinds += fmt::format("{}{} {}", kinds.empty() ? "" : ", ", k, v.get<uint64_t>());
        const json& sc = meta["scene"];
        const json& bv = meta["bvh"];
        fmt::print("rtsim run  config {} ({})  scene {} ({} triangles){}\n", cfg.typed.name,
                   cfg.hash(), sc.value("name", std::string("?")), sc.value("triangles", 0),
                   reader ? "  replayed from " + opt.trace_path : std::string());
        fmt::print(
            "  bvh      {} BVH{} {}: {} nodes, {} leaves, depth {}, SAH cost {:.2f}, {:.2f} MiB\n",
            bv.value("builder", std::string("?")), bv.value("width", 0),
            bv.value("node_format", std::string("?")), bv.value("nodes", 0), bv.value("leaves", 0),
            bv.value("max_depth", 0), bv.value("sah_cost", 0.0),
            bv.value("bytes", 0.0) / 1048576.0);
        fmt::print("  rays     {} ({}), {} steps\n", total_rays, kinds, source.steps);
        fmt::print("  cycles   {} = {:.3f} ms at {} GHz -> {:.2f} Mrays/s\n", ri.total_cycles,
                   sim_s * 1e3, ri.clock_ghz, out["rays_per_second"].get<double>() / 1e6);
        fmt::print("  units    box {:.1f}% busy, triangle {:.1f}% busy\n",
                   100 * un["box_unit_total"]["utilization"].get<double>(),
                   100 * un["triangle_unit_total"]["utilization"].get<double>());
        const json& share = out["stalls"]["total"]["share"];
        fmt::print(
            "  slots    issue {:.1f}%, L1 {:.1f}%, L2 {:.1f}%, DRAM {:.1f}%, box unit {:.1f}%, "
            "triangle unit {:.1f}%{}, no work {:.1f}%\n",
            100 * share["issue"].get<double>(), 100 * share["l1"].get<double>(),
            100 * share["l2"].get<double>(), 100 * share["dram"].get<double>(),
            100 * share["box_unit"].get<double>(), 100 * share["triangle_unit"].get<double>(),
            out.contains("ray_buffer")
                ? fmt::format(", ray buffer {:.1f}%", 100 * share["ray_buffer"].get<double>())
                : std::string(),
            100 * share["no_work"].get<double>());
        if (out.contains("ray_buffer")) {
            const json& rb = out["ray_buffer"];
            fmt::print(
                "  treelets {} batches of {:.1f} rays, {:.2f} crossings per ray, {:.1f} MB of "
                "treelets loaded, ray buffer {:.1f} MB moved, peak {} rays\n",
                rb["batches"].get<uint64_t>(), rb["rays_per_batch"].get<double>(),
                rb["crossings_per_ray"].get<double>(), rb["treelet_load_bytes"].get<double>() / 1e6,
                rb["bytes"].get<double>() / 1e6, rb["peak_rays"].get<uint64_t>());
        }
        if (out.contains("packets"))
            fmt::print("  packets  lane utilisation {:.1f}%\n",
                       100 * out["packets"]["lane_utilization"].get<double>());
        fmt::print("  caches   L1 hit rate {:.1f}%, L2 hit rate {:.1f}%\n",
                   100 * ca["l1_total"]["hit_rate"].get<double>(),
                   100 * ca["l2"]["hit_rate"].get<double>());
        fmt::print(
            "  traffic  L1 {:.1f} MB ({:.1f} GB/s), L2 {:.1f} MB ({:.1f} GB/s), DRAM {:.1f} MB "
            "({:.1f} GB/s)\n",
            bw["l1"]["bytes"].get<double>() / 1e6, bw["l1"]["gbps"].get<double>(),
            bw["l2"]["bytes"].get<double>() / 1e6, bw["l2"]["gbps"].get<double>(),
            bw["dram"]["bytes"].get<double>() / 1e6, bw["dram"]["gbps"].get<double>());
        fmt::print(
            "  host     {:.2f} s total, {:.2f} s simulating -> {:.3f} M simulated rays per host "
            "second\n",
            host_total, sim_seconds,
            out["host"]["simulated_rays_per_host_second"].get<double>() / 1e6);
        if (out.contains("bound"))
            fmt::print(
                "  bound    ideal memory and units: {:.2f} Mrays/s; achieved {:.1f}% of it\n",
                out["bound"]["rays_per_second"].get<double>() / 1e6,
                100 * out["bound"]["achieved_over_bound"].get<double>());
        fmt::print("  stats    {}\n", stats_path);
    }
    return 0;
}

}  // namespace rtsim
