// Parallax C++ API: a header-only C++17 RAII wrapper over the C API in parallax.h.
//
// - parallax::Context and parallax::Scene own their C handles; they are move-only.
// - Every failing call throws parallax::Error, which carries the plx_status and the library's
//   message.
// - Views into library memory (depth, mesh, surfaces) are parallax::Span / parallax::FloatGrid:
//   like the C views, they stay valid until the next call that changes the scene.
// - Images the library writes (photo, composite, mask) go into the host's plx_image_out, or into
//   a parallax::Image (std::vector<uint8_t> with width, height, stride and format).
// - Thread safety is that of the C API: a Context may be shared by threads; a Scene is used by
//   one thread at a time (Scene::clone gives another scene sharing the reconstruction).
//
// No dependency besides the C library and the standard library. Link with -lparallax.
#ifndef PARALLAX_HPP
#define PARALLAX_HPP

#include <array>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <functional>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "parallax.h"

namespace parallax {

/// The status of a failed call (the C enum, scoped).
using Status = plx_status;

/// A failed call: its status and the library's message.
class Error : public std::runtime_error {
public:
    Error(Status status, const std::string& message)
        : std::runtime_error(message), status_(status) {}
    /// The plx_status the call returned.
    Status status() const noexcept { return status_; }

private:
    Status status_;
};

namespace detail {
/// The last error message of `handle` (a plx_context*, plx_scene* or NULL for the global one).
inline std::string last_error(const void* handle) {
    size_t needed = 0;
    if (plx_last_error_message(handle, nullptr, 0, &needed) != PLX_STATUS_OK || needed <= 1)
        return {};
    std::string text(needed, '\0');
    plx_last_error_message(handle, text.data(), text.size(), nullptr);
    text.resize(needed - 1);
    return text;
}

inline void check(plx_status status, const void* handle) {
    if (status != PLX_STATUS_OK) {
        std::string message = last_error(handle);
        if (message.empty()) message = plx_status_str(static_cast<uint32_t>(status));
        throw Error(status, message);
    }
}

/// Copies a string out of a snprintf-like C function `fill(buf, len, needed)`.
template <class Fill>
std::string read_string(Fill fill) {
    size_t needed = 0;
    fill(nullptr, 0, &needed);
    std::string text(needed, '\0');
    if (needed > 0) fill(text.data(), text.size(), &needed);
    if (!text.empty()) text.resize(text.size() - 1);
    return text;
}
}  // namespace detail

/// A read-only view of `size()` contiguous values in library memory (C++17 stand-in for
/// std::span<const T>).
template <class T>
class Span {
public:
    Span() = default;
    Span(const T* data, size_t size) : data_(data), size_(size) {}
    const T* data() const noexcept { return data_; }
    size_t size() const noexcept { return size_; }
    bool empty() const noexcept { return size_ == 0; }
    const T* begin() const noexcept { return data_; }
    const T* end() const noexcept { return data_ + size_; }
    const T& operator[](size_t i) const { return data_[i]; }

private:
    const T* data_ = nullptr;
    size_t size_ = 0;
};

/// A grid of floats in library memory (disparity, confidence, depth, depth buffers).
struct FloatGrid {
    const float* data = nullptr;
    uint32_t width = 0;
    uint32_t height = 0;
    /// Bytes from one row to the next.
    size_t stride = 0;

    /// Row `y` as a span of `width` floats.
    Span<float> row(uint32_t y) const {
        return {reinterpret_cast<const float*>(reinterpret_cast<const uint8_t*>(data) + y * stride),
                width};
    }
    /// The value at column `x`, row `y`.
    float at(uint32_t x, uint32_t y) const { return row(y)[x]; }

    static FloatGrid from(const plx_float_view& v) { return {v.data, v.width, v.height, v.stride}; }
};

/// The scene mesh (camera frame, metres), a view into library memory.
struct Mesh {
    Span<float> positions;  ///< 3 per vertex
    Span<float> normals;    ///< 3 per vertex
    Span<float> tangents;   ///< 4 per vertex
    Span<float> uvs;        ///< 2 per vertex
    Span<uint32_t> indices; ///< 3 per triangle
    size_t vertex_count = 0;
    size_t triangle_count() const noexcept { return indices.size() / 3; }
};

/// A column-major 4×4 matrix (OpenGL / glTF / Unity element order).
using Matrix4 = std::array<float, 16>;
/// A 3-vector.
using Vec3 = std::array<float, 3>;

/// Bounding boxes of an artefact, metres.
struct Bounds {
    Vec3 local_min, local_max, world_min, world_max;
};

/// An image owned by the host: `height` rows of `stride` bytes of `format` pixels
/// (plx_pixel_format), e.g. the composite from Scene::render.
struct Image {
    std::vector<uint8_t> pixels;
    uint32_t width = 0;
    uint32_t height = 0;
    /// Bytes from one row to the next.
    size_t stride = 0;
    plx_pixel_format format = PLX_PIXEL_FORMAT_RGBA8;

    /// Bytes per pixel of `format` (0 for an unknown one).
    static size_t bytes_per_pixel(plx_pixel_format format) noexcept {
        switch (format) {
            case PLX_PIXEL_FORMAT_GRAY8: return 1;
            case PLX_PIXEL_FORMAT_RGB8: return 3;
            case PLX_PIXEL_FORMAT_RGBA8:
            case PLX_PIXEL_FORMAT_BGRA8:
            case PLX_PIXEL_FORMAT_GRAY_F32: return 4;
            case PLX_PIXEL_FORMAT_RGB_F32: return 12;
            case PLX_PIXEL_FORMAT_RGBA_F16: return 8;
            case PLX_PIXEL_FORMAT_RGBA_F32: return 16;
        }
        return 0;
    }
    /// A zeroed `width × height` image of `format` with tightly packed rows.
    static Image allocate(uint32_t width, uint32_t height, plx_pixel_format format) {
        Image image;
        image.width = width;
        image.height = height;
        image.format = format;
        image.stride = static_cast<size_t>(width) * bytes_per_pixel(format);
        image.pixels.assign(image.stride * height, 0);
        return image;
    }
    /// The C descriptor for the library to write into (valid while `pixels` is not resized).
    plx_image_out out() noexcept {
        return plx_image_out{pixels.data(), width, height, stride, static_cast<uint32_t>(format)};
    }
    /// The C descriptor for the library to read from.
    plx_image view() const noexcept {
        return plx_image{pixels.data(), width, height, stride, static_cast<uint32_t>(format)};
    }
    /// First byte of pixel (x, y).
    const uint8_t* at(uint32_t x, uint32_t y) const {
        return pixels.data() + y * stride + x * bytes_per_pixel(format);
    }
};

/// The main light as AR platforms give it (plx_scene_main_light).
struct MainLight {
    /// Unit vector from the scene towards the light (zero without a light).
    Vec3 direction;
    /// Linear RGB intensity.
    Vec3 rgb;
};

/// Nine RGB spherical-harmonics coefficients, ARCore order (see plx_scene_set_sh9).
using Sh9 = std::array<float, 27>;

/// A status as text (plx_status_str).
inline std::string status_str(Status status) {
    return plx_status_str(static_cast<uint32_t>(status));
}

/// Levels of the log callback.
enum class LogLevel : uint32_t {
    Error = PLX_LOG_LEVEL_ERROR,
    Warn = PLX_LOG_LEVEL_WARN,
    Info = PLX_LOG_LEVEL_INFO,
    Debug = PLX_LOG_LEVEL_DEBUG,
};

/// The process-wide log callback (see plx_set_log_callback): `callback(level, message)` up to
/// `max_level`; an empty function removes it. The callback may run on any thread that calls
/// Parallax; exceptions it throws are swallowed.
inline void set_log_callback(std::function<void(LogLevel, std::string_view)> callback,
                             LogLevel max_level = LogLevel::Warn) {
    // One holder for the process; replaced under a lock, and kept alive until after the C
    // library stops calling the old one.
    static std::mutex lock;
    static std::unique_ptr<std::function<void(LogLevel, std::string_view)>> holder;
    std::lock_guard<std::mutex> guard(lock);
    auto next = callback ? std::make_unique<std::function<void(LogLevel, std::string_view)>>(
                               std::move(callback))
                         : nullptr;
    auto trampoline = [](void* user, uint32_t level, const char* message) {
        try {
            (*static_cast<std::function<void(LogLevel, std::string_view)>*>(user))(
                static_cast<LogLevel>(level), message);
        } catch (...) {
        }
    };
    detail::check(plx_set_log_callback(next ? +trampoline : nullptr, next.get(),
                                       static_cast<uint32_t>(max_level)),
                  nullptr);
    holder = std::move(next);
}

/// The library version string, e.g. "0.1.0".
inline std::string version() { return plx_version(); }

/// Options shared by scenes; owns a plx_context. Thread-safe.
class Context {
public:
    /// A context with the default options.
    Context() : Context(default_options()) {}
    /// A context with `options` (start from Context::default_options()).
    explicit Context(const plx_context_options& options) {
        detail::check(plx_context_new(&options, &handle_), nullptr);
    }
    Context(Context&& other) noexcept : handle_(std::exchange(other.handle_, nullptr)) {}
    Context& operator=(Context&& other) noexcept {
        if (this != &other) {
            plx_context_free(handle_);
            handle_ = std::exchange(other.handle_, nullptr);
        }
        return *this;
    }
    Context(const Context&) = delete;
    Context& operator=(const Context&) = delete;
    ~Context() { plx_context_free(handle_); }

    static plx_context_options default_options() {
        plx_context_options o;
        detail::check(plx_context_options_init(&o), nullptr);
        return o;
    }
    /// The C handle (still owned by this object).
    plx_context* get() const noexcept { return handle_; }

private:
    plx_context* handle_ = nullptr;
};

/// A photo's reconstruction and what is inserted into it; owns a plx_scene. One thread at a time.
class Scene {
public:
    /// Progress callback: (stage, fraction 0 or 1) → true to go on, false to cancel (the call
    /// then throws Error with PLX_STATUS_CANCELLED). An exception thrown by the callback cancels
    /// the call and is rethrown from it.
    using Progress = std::function<bool(std::string_view stage, float fraction)>;

    /// An empty scene in `context` (which may be destroyed first: the scene keeps what it needs).
    explicit Scene(const Context& context) {
        detail::check(plx_scene_new(context.get(), &handle_), context.get());
    }
    Scene(Scene&& other) noexcept
        : handle_(std::exchange(other.handle_, nullptr)), progress_(std::move(other.progress_)) {}
    Scene& operator=(Scene&& other) noexcept {
        if (this != &other) {
            plx_scene_free(handle_);
            handle_ = std::exchange(other.handle_, nullptr);
            progress_ = std::move(other.progress_);
        }
        return *this;
    }
    Scene(const Scene&) = delete;
    Scene& operator=(const Scene&) = delete;
    ~Scene() { plx_scene_free(handle_); }

    /// The C handle (still owned by this object).
    plx_scene* get() const noexcept { return handle_; }

    /// A new scene sharing this one's inputs and computed products (plx_scene_clone).
    Scene clone() const {
        plx_scene* copy = nullptr;
        check(plx_scene_clone(handle_, &copy));
        Scene out(copy);
        // The C copy points at this scene's callback holder; give it its own.
        out.set_progress_callback(progress_ ? progress_->callback : Progress());
        return out;
    }

    // ---- inputs -------------------------------------------------------------------------

    void set_stereo_pair(const plx_image& left, const plx_image& right) {
        check(plx_scene_set_stereo_pair(handle_, &left, &right));
    }
    /// The photo alone, for a host that gives its own depth (set_depth).
    void set_photo(const plx_image& photo) { check(plx_scene_set_photo(handle_, &photo)); }
    /// Reads the pair from image files (PNG, JPEG, EXR, HDR).
    void load_stereo_pair(const std::string& left_path, const std::string& right_path) {
        check(plx_scene_load_stereo_pair(handle_, left_path.c_str(), right_path.c_str()));
    }
    void set_calibration(const plx_calibration& calibration) {
        check(plx_scene_set_calibration(handle_, &calibration));
    }
    static plx_stereo_options default_stereo_options() {
        plx_stereo_options o;
        detail::check(plx_stereo_options_init(&o), nullptr);
        return o;
    }
    void set_stereo_options(const plx_stereo_options& options) {
        check(plx_scene_set_stereo_options(handle_, &options));
    }
    void reset_stereo_options() { check(plx_scene_set_stereo_options(handle_, nullptr)); }
    /// The host's own depth (metres), optional confidence and camera; strides in bytes.
    void set_depth(const float* depth, uint32_t width, uint32_t height, size_t stride_bytes,
                   const float* confidence = nullptr, size_t confidence_stride_bytes = 0,
                   const plx_camera* camera = nullptr) {
        check(plx_scene_set_depth(handle_, depth, width, height, stride_bytes, confidence,
                                  confidence_stride_bytes, camera));
    }
    void clear_depth() { check(plx_scene_clear_depth(handle_)); }
    /// Clip range in metres; (0, 0) = automatic.
    void set_clip(float near_m, float far_m) { check(plx_scene_set_clip(handle_, near_m, far_m)); }
    static plx_mesh_options default_mesh_options() {
        plx_mesh_options o;
        detail::check(plx_mesh_options_init(&o), nullptr);
        return o;
    }
    void set_mesh_options(const plx_mesh_options& options) {
        check(plx_scene_set_mesh_options(handle_, &options));
    }
    void set_progress_callback(Progress callback) {
        std::unique_ptr<ProgressHolder> next;
        if (callback) next = std::make_unique<ProgressHolder>(ProgressHolder{std::move(callback), {}});
        check(plx_scene_set_progress_callback(handle_, next ? &progress_trampoline : nullptr,
                                              next.get()));
        progress_ = std::move(next);
    }

    // ---- products ------------------------------------------------------------------------

    FloatGrid disparity() { return grid(plx_scene_disparity); }
    FloatGrid confidence() { return grid(plx_scene_confidence); }
    FloatGrid depth() { return grid(plx_scene_depth); }
    /// Depth for a host depth buffer (`encoding`: plx_depth_encoding); clip (0, 0) = the camera's.
    FloatGrid depth_buffer(plx_depth_encoding encoding, float near_m = 0, float far_m = 0) {
        plx_float_view v{};
        check(plx_scene_depth_buffer(handle_, static_cast<uint32_t>(encoding), near_m, far_m, &v));
        return FloatGrid::from(v);
    }
    struct CameraInfo {
        plx_camera intrinsics;
        float near_m, far_m;
    };
    CameraInfo camera() {
        CameraInfo c{};
        check(plx_scene_camera(handle_, &c.intrinsics, &c.near_m, &c.far_m));
        return c;
    }
    Mesh mesh() {
        plx_mesh_view v{};
        check(plx_scene_mesh(handle_, &v));
        Mesh m;
        m.vertex_count = v.vertex_count;
        m.positions = {v.positions, 3 * v.vertex_count};
        m.normals = {v.normals, 3 * v.vertex_count};
        m.tangents = {v.tangents, 4 * v.vertex_count};
        m.uvs = {v.uvs, 2 * v.vertex_count};
        m.indices = {v.indices, v.index_count};
        return m;
    }
    Span<plx_surface> surfaces() {
        size_t count = 0;
        const plx_surface* list = nullptr;
        check(plx_scene_surfaces(handle_, &count, &list));
        return {list, count};
    }
    Vec3 up() {
        Vec3 v{};
        check(plx_scene_up(handle_, v.data()));
        return v;
    }
    /// The host's gravity up (e.g. from an IMU), camera frame, any length.
    void set_up(const Vec3& up) { check(plx_scene_set_up(handle_, up.data())); }
    /// Back to the up estimated from the planes.
    void reset_up() { check(plx_scene_set_up(handle_, nullptr)); }
    plx_hit pick(float x, float y) {
        plx_hit h{};
        check(plx_scene_pick(handle_, x, y, &h));
        return h;
    }
    Matrix4 place(float x, float y, float size_m, float yaw_deg = 0) {
        Matrix4 m{};
        check(plx_scene_place(handle_, x, y, size_m, yaw_deg, m.data()));
        return m;
    }
    Matrix4 place_on_ray(const Vec3& origin, const Vec3& direction, float size_m, float yaw_deg = 0) {
        Matrix4 m{};
        check(plx_scene_place_on_ray(handle_, origin.data(), direction.data(), size_m, yaw_deg,
                                     m.data()));
        return m;
    }
    /// Writes the photo into the host's image, in its format and stride.
    void photo(const plx_image_out& out) { check(plx_scene_photo(handle_, &out)); }
    /// The photo's size (width, height): the size of every image output.
    std::pair<uint32_t, uint32_t> photo_size() {
        uint32_t w = 0, h = 0;
        check(plx_scene_photo_size(handle_, &w, &h));
        return {w, h};
    }
    /// The photo in a new image of `format`.
    Image photo(plx_pixel_format format = PLX_PIXEL_FORMAT_RGBA8) {
        const auto size = photo_size();
        Image image = Image::allocate(size.first, size.second, format);
        photo(image.out());
        return image;
    }

    // ---- composite -----------------------------------------------------------------------

    static plx_render_options default_render_options() {
        plx_render_options o;
        detail::check(plx_render_options_init(&o), nullptr);
        return o;
    }
    /// Renders the composite into the host's image `out` (any format and stride, the photo's
    /// size) and, when `mask` is not null, the artefacts' coverage into `*mask`. `options` null
    /// = the defaults.
    void render(const plx_image_out& out, const plx_image_out* mask = nullptr,
                const plx_render_options* options = nullptr) {
        check(plx_scene_render(handle_, options, &out, mask));
    }
    /// Renders the composite into a new image of `format`; the coverage into `*mask` (a new
    /// GRAY8 image) when `mask` is not null.
    Image render(plx_pixel_format format, Image* mask = nullptr,
                 const plx_render_options* options = nullptr) {
        const auto size = photo_size();
        Image image = Image::allocate(size.first, size.second, format);
        const plx_image_out out = image.out();
        if (mask) {
            Image m = Image::allocate(size.first, size.second, PLX_PIXEL_FORMAT_GRAY8);
            const plx_image_out mask_out = m.out();
            check(plx_scene_render(handle_, options, &out, &mask_out));
            *mask = std::move(m);
        } else {
            check(plx_scene_render(handle_, options, &out, nullptr));
        }
        return image;
    }

    // ---- lighting ------------------------------------------------------------------------

    /// The lights in use (the host's, else the estimated ones).
    std::vector<plx_light> lights() {
        size_t count = 0;
        check(plx_scene_lights(handle_, nullptr, 0, &count));
        std::vector<plx_light> out(count);
        if (count > 0) check(plx_scene_lights(handle_, out.data(), out.size(), &count));
        out.resize(count < out.size() ? count : out.size());
        return out;
    }
    /// Replaces the estimated lights (an empty list: no direct light).
    void set_lights(const std::vector<plx_light>& lights) {
        check(plx_scene_set_lights(handle_, lights.empty() ? nullptr : lights.data(),
                                   lights.size()));
    }
    /// Back to the estimated lights.
    void reset_lights() { check(plx_scene_reset_lights(handle_)); }
    MainLight main_light() {
        MainLight l{};
        check(plx_scene_main_light(handle_, l.direction.data(), l.rgb.data()));
        return l;
    }
    /// The ambient light (the host's, else projected from the environment).
    Sh9 sh9() {
        Sh9 v{};
        check(plx_scene_sh9(handle_, v.data()));
        return v;
    }
    void set_sh9(const Sh9& sh9) { check(plx_scene_set_sh9(handle_, sh9.data())); }
    /// Back to the estimated ambient light.
    void reset_sh9() { check(plx_scene_set_sh9(handle_, nullptr)); }
    /// Where the objects will go (camera frame, metres): the estimated environment is built
    /// around it.
    void set_insertion_point(const std::array<float, 3>& point) {
        check(plx_scene_set_insertion_point(handle_, point.data()));
    }
    /// Back to the default insertion point (the median up-facing surface point).
    void reset_insertion_point() { check(plx_scene_set_insertion_point(handle_, nullptr)); }
    /// The host's equirectangular environment map (2:1, copied).
    void set_environment_equirect(const plx_image& image) {
        check(plx_scene_set_environment_equirect(handle_, &image));
    }
    /// Back to the estimated environment.
    void reset_environment() { check(plx_scene_set_environment_equirect(handle_, nullptr)); }
    /// Edge length in texels of each environment cube face.
    uint32_t environment_cube_size() {
        uint32_t size = 0;
        check(plx_scene_environment_cube_size(handle_, &size));
        return size;
    }
    /// Writes cube face `face` (0 +X, 1 −X, 2 +Y, 3 −Y, 4 +Z, 5 −Z) into the host's image.
    void environment_cube_face(uint32_t face, const plx_image_out& out) {
        check(plx_scene_environment_cube_face(handle_, face, &out));
    }
    /// Cube face `face` in a new image of `format` (RGBA_F16 for a GPU's RGBA16F cube).
    Image environment_cube_face(uint32_t face,
                                plx_pixel_format format = PLX_PIXEL_FORMAT_RGBA_F16) {
        const uint32_t size = environment_cube_size();
        Image image = Image::allocate(size, size, format);
        environment_cube_face(face, image.out());
        return image;
    }
    /// The JSON report of the last call that computed or fetched a product.
    std::string report() {
        return detail::read_string([&](char* buf, size_t len, size_t* needed) {
            check(plx_scene_report(handle_, buf, len, needed));
        });
    }

    // ---- artefacts -----------------------------------------------------------------------

    using ArtefactId = uint32_t;
    ArtefactId add_artefact(const std::string& path, const Matrix4* transform = nullptr) {
        ArtefactId id = 0;
        check(plx_scene_add_artefact_path(handle_, path.c_str(),
                                          transform ? transform->data() : nullptr, &id));
        return id;
    }
    ArtefactId add_artefact(Span<uint8_t> bytes, const Matrix4* transform = nullptr) {
        ArtefactId id = 0;
        check(plx_scene_add_artefact_memory(handle_, bytes.data(), bytes.size(),
                                            transform ? transform->data() : nullptr, &id));
        return id;
    }
    void set_artefact_transform(ArtefactId id, const Matrix4& transform) {
        check(plx_scene_set_artefact_transform(handle_, id, transform.data()));
    }
    void set_artefact_flags(ArtefactId id, bool visible, bool casts_shadow, bool receives_shadow) {
        check(plx_scene_set_artefact_flags(handle_, id, visible, casts_shadow, receives_shadow));
    }
    void remove_artefact(ArtefactId id) { check(plx_scene_remove_artefact(handle_, id)); }
    Bounds artefact_bounds(ArtefactId id) {
        Bounds b{};
        check(plx_artefact_bounds(handle_, id, b.local_min.data(), b.local_max.data(),
                                  b.world_min.data(), b.world_max.data()));
        return b;
    }
    Matrix4 place_artefact(ArtefactId id, float x, float y, float size_m, float yaw_deg = 0) {
        Matrix4 m{};
        check(plx_scene_place_artefact(handle_, id, x, y, size_m, yaw_deg, m.data()));
        return m;
    }
    /// The loader's warnings for `id`, one per element.
    std::vector<std::string> artefact_warnings(ArtefactId id) {
        std::string all = detail::read_string([&](char* buf, size_t len, size_t* needed) {
            check(plx_scene_artefact_warnings(handle_, id, buf, len, needed, nullptr));
        });
        std::vector<std::string> out;
        size_t start = 0;
        while (!all.empty() && start <= all.size()) {
            size_t end = all.find('\n', start);
            if (end == std::string::npos) end = all.size();
            out.push_back(all.substr(start, end - start));
            start = end + 1;
        }
        return out;
    }

private:
    struct ProgressHolder {
        Progress callback;
        std::exception_ptr error;
    };

    explicit Scene(plx_scene* handle) : handle_(handle) {}

    static int32_t progress_trampoline(void* user, const char* stage, float fraction) {
        auto* holder = static_cast<ProgressHolder*>(user);
        try {
            return holder->callback(stage, fraction) ? 0 : 1;
        } catch (...) {
            holder->error = std::current_exception();
            return 1;
        }
    }

    void check(plx_status status) const {
        if (status == PLX_STATUS_CANCELLED && progress_ && progress_->error)
            std::rethrow_exception(std::exchange(progress_->error, nullptr));
        detail::check(status, handle_);
    }

    FloatGrid grid(plx_status (*fn)(plx_scene*, plx_float_view*)) {
        plx_float_view v{};
        check(fn(handle_, &v));
        return FloatGrid::from(v);
    }

    plx_scene* handle_ = nullptr;
    std::unique_ptr<ProgressHolder> progress_;
};

#if defined(PLX_FEATURE_UNITY)
/// Unity's render-thread events (library built with the `unity` feature; define
/// PLX_FEATURE_UNITY before including). Unity itself calls UnityPluginLoad, UnityPluginUnload and
/// GetRenderEventFunc; the host registers what each event id renders.
namespace unity {
/// Event `event_id` renders `scene`'s composite into `out` (and the coverage into `*mask`); the
/// scene and the buffers must outlive the registration (see plx_unity_set_render_target).
inline void set_render_target(int32_t event_id, Scene& scene, const plx_image_out& out,
                              const plx_image_out* mask = nullptr,
                              const plx_render_options* options = nullptr) {
    detail::check(plx_unity_set_render_target(event_id, scene.get(), options, &out, mask),
                  nullptr);
}
/// Event `event_id` renders nothing any more.
inline void clear_render_target(int32_t event_id) {
    detail::check(plx_unity_set_render_target(event_id, nullptr, nullptr, nullptr, nullptr),
                  nullptr);
}
/// The status of the event's last run (NOT_AVAILABLE if it never ran) and its run count.
inline Status last_event_status(int32_t event_id, uint64_t* runs = nullptr) {
    return plx_unity_last_event_status(event_id, runs);
}
/// The message of the event's last run ("" after a success).
inline std::string last_event_message(int32_t event_id) {
    return detail::read_string([&](char* buf, size_t len, size_t* needed) {
        detail::check(plx_unity_last_event_message(event_id, buf, len, needed), nullptr);
    });
}
/// The interface table Unity gave UnityPluginLoad (null when not loaded).
inline const plx_unity_interfaces* interfaces() noexcept { return plx_unity_interfaces_get(); }
}  // namespace unity
#endif

}  // namespace parallax

#endif  // PARALLAX_HPP
