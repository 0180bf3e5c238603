/* What hosts need around the stages: the log callback, progress with cancellation, a busy scene
 * refusing re-entrant calls, plx_scene_clone sharing the reconstruction, images written into host
 * memory in every format and stride (plx_scene_photo), and stereo pairs read from files. */
#include <math.h>
#include <time.h>

#include "check.h"

enum { W = 96, H = 48, SHIFT = 6 };

static uint8_t texture(long x, long y) {
    unsigned long long v = (unsigned long long)(x * 73856093L) ^ (unsigned long long)(y * 19349663L);
    v ^= v >> 13;
    v *= 0x5bd1e995ull;
    return (uint8_t)(v >> 24);
}

/* ---- log ---------------------------------------------------------------------------------- */

typedef struct {
    int lines[4];
    char last_error[512];
    int saw_stereo_computed, saw_reused;
} log_record;

static void on_log(void *user_data, uint32_t level, const char *message) {
    log_record *r = user_data;
    if (level < 4) r->lines[level]++;
    if (level == PLX_LOG_LEVEL_ERROR) snprintf(r->last_error, sizeof r->last_error, "%s", message);
    if (level == PLX_LOG_LEVEL_INFO && strstr(message, "stereo computed in")) r->saw_stereo_computed = 1;
    if (level == PLX_LOG_LEVEL_DEBUG && strstr(message, "reused")) r->saw_reused = 1;
}

/* ---- progress ----------------------------------------------------------------------------- */

typedef struct {
    plx_scene *scene;
    const char *cancel_stage; /* cancel when this stage reports cancel_at */
    float cancel_at;
    int events;
    int started_stereo, finished_stereo;
    plx_status reentrant; /* status of a call made on the busy scene from inside the callback */
    int try_reentry;
} progress_record;

static int32_t on_progress(void *user_data, const char *stage, float fraction) {
    progress_record *p = user_data;
    p->events++;
    if (strcmp(stage, "stereo") == 0) {
        if (fraction == 0.0f) p->started_stereo++;
        if (fraction == 1.0f) p->finished_stereo++;
    }
    if (p->try_reentry) {
        plx_float_view v;
        p->reentrant = plx_scene_depth(p->scene, &v);
        plx_scene_free(p->scene); /* must be refused while the scene is busy */
        p->try_reentry = 0;
    }
    return p->cancel_stage && strcmp(stage, p->cancel_stage) == 0 && fraction == p->cancel_at;
}

static int report_has(plx_scene *scene, const char *stage, const char *status) {
    char report[16384], needle[128];
    if (plx_scene_report(scene, report, sizeof report, NULL) != PLX_STATUS_OK) return 0;
    snprintf(needle, sizeof needle, "\"name\": \"%s\",\n      \"status\": \"%s\"", stage, status);
    return strstr(report, needle) != NULL;
}

/* ---- a stored (uncompressed) PNG writer, so the file loader can be tested without data ------ */

static uint32_t crc_table[256];
static void crc_init(void) {
    for (uint32_t n = 0; n < 256; n++) {
        uint32_t c = n;
        for (int k = 0; k < 8; k++) c = c & 1 ? 0xedb88320u ^ (c >> 1) : c >> 1;
        crc_table[n] = c;
    }
}
static uint32_t crc(const uint8_t *p, size_t n, uint32_t c) {
    c = ~c;
    while (n--) c = crc_table[(c ^ *p++) & 0xff] ^ (c >> 8);
    return ~c;
}
static void be32(FILE *f, uint32_t v) {
    uint8_t b[4] = {(uint8_t)(v >> 24), (uint8_t)(v >> 16), (uint8_t)(v >> 8), (uint8_t)v};
    fwrite(b, 1, 4, f);
}
static void chunk(FILE *f, const char *type, const uint8_t *data, uint32_t len) {
    be32(f, len);
    fwrite(type, 1, 4, f);
    if (len) fwrite(data, 1, len, f);
    uint32_t c = crc((const uint8_t *)type, 4, 0);
    be32(f, crc(data, len, c));
}
/* 8-bit greyscale, one zlib stored block (the image is small). */
static int write_png_gray(const char *path, const uint8_t *pixels, unsigned w, unsigned h) {
    FILE *f = fopen(path, "wb");
    if (!f) return 0;
    static const uint8_t sig[8] = {137, 80, 78, 71, 13, 10, 26, 10};
    fwrite(sig, 1, 8, f);
    uint8_t ihdr[13] = {(uint8_t)(w >> 24), (uint8_t)(w >> 16), (uint8_t)(w >> 8), (uint8_t)w,
                        (uint8_t)(h >> 24), (uint8_t)(h >> 16), (uint8_t)(h >> 8), (uint8_t)h,
                        8, 0, 0, 0, 0};
    chunk(f, "IHDR", ihdr, 13);
    size_t raw_len = (size_t)h * (w + 1);
    static uint8_t idat[2 + 5 + H * (W + 1) + 4];
    uint8_t *raw = idat + 7;
    for (unsigned y = 0; y < h; y++) {
        raw[y * (w + 1)] = 0; /* filter: none */
        memcpy(raw + y * (w + 1) + 1, pixels + y * w, w);
    }
    idat[0] = 0x78, idat[1] = 0x01;
    idat[2] = 1; /* final stored block */
    idat[3] = (uint8_t)raw_len, idat[4] = (uint8_t)(raw_len >> 8);
    idat[5] = (uint8_t)~raw_len, idat[6] = (uint8_t)(~raw_len >> 8);
    uint32_t a = 1, b = 0;
    for (size_t i = 0; i < raw_len; i++) a = (a + raw[i]) % 65521, b = (b + a) % 65521;
    uint8_t *ad = raw + raw_len;
    ad[0] = (uint8_t)(b >> 8), ad[1] = (uint8_t)b, ad[2] = (uint8_t)(a >> 8), ad[3] = (uint8_t)a;
    chunk(f, "IDAT", idat, (uint32_t)(7 + raw_len + 4));
    chunk(f, "IEND", NULL, 0);
    return fclose(f) == 0;
}

static double srgb_to_linear(double c) {
    return c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4);
}

/* IEEE half → float (normal and zero values only, enough for colours in [0, 1]). */
static float half_to_float(uint16_t h) {
    int e = (h >> 10) & 31, m = h & 1023;
    if (e == 0) return ldexpf((float)m, -24);
    return ldexpf((float)(m | 1024), e - 25);
}

int main(void) {
    static uint8_t left[W * H], right[W * H];
    for (long y = 0; y < H; y++)
        for (long x = 0; x < W; x++) {
            left[y * W + x] = texture(x, y);
            right[y * W + x] = texture(x + SHIFT, y);
        }
    plx_context *ctx = NULL;
    plx_scene *scene = NULL;
    CHECK_STATUS(NULL, plx_context_new(NULL, &ctx), PLX_STATUS_OK);
    CHECK_STATUS(ctx, plx_scene_new(ctx, &scene), PLX_STATUS_OK);

    /* Log: errors, warnings, computed (info) and reused (debug) products reach the callback. */
    log_record logged = {{0}, "", 0, 0};
    CHECK_STATUS(NULL, plx_set_log_callback(on_log, &logged, 7), PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(NULL, "max_level");
    CHECK_STATUS(NULL, plx_set_log_callback(on_log, &logged, PLX_LOG_LEVEL_DEBUG), PLX_STATUS_OK);
    plx_float_view view;
    CHECK_STATUS(scene, plx_scene_disparity(scene, &view), PLX_STATUS_NOT_AVAILABLE);
    CHECK(logged.lines[PLX_LOG_LEVEL_ERROR] == 1);
    CHECK(strstr(logged.last_error, "stereo pair") != NULL);

    plx_image l = {left, W, H, W, PLX_PIXEL_FORMAT_GRAY8};
    plx_image r = {right, W, H, W, PLX_PIXEL_FORMAT_GRAY8};
    CHECK_STATUS(scene, plx_scene_set_stereo_pair(scene, &l, &r), PLX_STATUS_OK);
    plx_stereo_options opts;
    plx_stereo_options_init(&opts);
    opts.max_disparity = 16;
    CHECK_STATUS(scene, plx_scene_set_stereo_options(scene, &opts), PLX_STATUS_OK);

    /* Progress: cancel before stereo starts. Nothing is computed; the message says where. */
    progress_record prog = {scene, "stereo", 0.0f, 0, 0, 0, PLX_STATUS_OK, 0};
    CHECK_STATUS(scene, plx_scene_set_progress_callback(scene, on_progress, &prog), PLX_STATUS_OK);
    CHECK_STATUS(scene, plx_scene_depth(scene, &view), PLX_STATUS_CANCELLED);
    CHECK_MESSAGE(scene, "before `stereo`");
    CHECK(prog.started_stereo == 1 && prog.finished_stereo == 0);
    CHECK(logged.lines[PLX_LOG_LEVEL_ERROR] == 2);
    CHECK(!logged.saw_stereo_computed);

    /* Cancel right after stereo: the call fails, but the disparity is kept and reused next. */
    prog.cancel_at = 1.0f;
    CHECK_STATUS(scene, plx_scene_depth(scene, &view), PLX_STATUS_CANCELLED);
    CHECK_MESSAGE(scene, "after `stereo`");
    CHECK(prog.finished_stereo == 1);
    CHECK(logged.saw_stereo_computed);
    prog.cancel_stage = NULL;
    CHECK_STATUS(scene, plx_scene_depth(scene, &view), PLX_STATUS_OK);
    CHECK(report_has(scene, "stereo", "reused"));
    CHECK(report_has(scene, "depth", "computed"));
    CHECK(prog.started_stereo == 2); /* not started again */
    CHECK(logged.saw_reused);
    /* No calibration: depth is up to scale, and that warning reached the log. */
    CHECK(logged.lines[PLX_LOG_LEVEL_WARN] >= 1);

    /* A callback calling back into its busy scene gets an error, and cannot free it. */
    plx_calibration calib = {600.0, W / 2.0, H / 2.0, 0.1, 0.0, 0};
    CHECK_STATUS(scene, plx_scene_set_calibration(scene, &calib), PLX_STATUS_OK);
    prog.try_reentry = 1;
    CHECK_STATUS(scene, plx_scene_depth(scene, &view), PLX_STATUS_OK);
    CHECK(prog.reentrant == PLX_STATUS_INVALID_ARGUMENT);
    CHECK(fabsf(*(const float *)((const uint8_t *)view.data + 24 * view.stride + 60 * 4) - 10.0f) < 0.5f);

    /* The log callback stops when removed. */
    CHECK_STATUS(NULL, plx_set_log_callback(NULL, NULL, PLX_LOG_LEVEL_DEBUG), PLX_STATUS_OK);
    int before = logged.lines[PLX_LOG_LEVEL_ERROR];
    CHECK_STATUS(scene, plx_scene_depth(scene, NULL), PLX_STATUS_NULL_ARGUMENT);
    CHECK(logged.lines[PLX_LOG_LEVEL_ERROR] == before);
    CHECK_STATUS(scene, plx_scene_set_progress_callback(scene, NULL, NULL), PLX_STATUS_OK);
    int events = prog.events;
    CHECK_STATUS(scene, plx_scene_surfaces(scene, &(size_t){0}, &(const plx_surface *){NULL}),
                 PLX_STATUS_OK);
    CHECK(prog.events == events);

    /* Clone: the copy shares the mesh (same memory, reused), then changes on its own. */
    plx_mesh_view mesh_a, mesh_b;
    CHECK_STATUS(scene, plx_scene_mesh(scene, &mesh_a), PLX_STATUS_OK);
    plx_scene *copy = NULL;
    CHECK_STATUS(scene, plx_scene_clone(scene, NULL), PLX_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(NULL, plx_scene_clone(NULL, &copy), PLX_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(scene, plx_scene_clone(scene, &copy), PLX_STATUS_OK);
    CHECK_STATUS(copy, plx_scene_mesh(copy, &mesh_b), PLX_STATUS_OK);
    CHECK(mesh_b.positions == mesh_a.positions && mesh_b.index_count == mesh_a.index_count);
    CHECK(report_has(copy, "mesh", "reused") && report_has(copy, "stereo", "reused"));
    plx_mesh_options mo;
    plx_mesh_options_init(&mo);
    mo.step = 4;
    CHECK_STATUS(copy, plx_scene_set_mesh_options(copy, &mo), PLX_STATUS_OK);
    CHECK_STATUS(copy, plx_scene_mesh(copy, &mesh_b), PLX_STATUS_OK);
    CHECK(mesh_b.vertex_count < mesh_a.vertex_count);
    CHECK(report_has(copy, "mesh.grid", "computed") && report_has(copy, "stereo", "reused"));
    CHECK_STATUS(scene, plx_scene_mesh(scene, &mesh_a), PLX_STATUS_OK);
    CHECK(report_has(scene, "mesh", "reused")); /* the original did not change */
    /* Either may be freed first. */
    plx_scene_free(scene);
    scene = copy;
    CHECK_STATUS(scene, plx_scene_depth(scene, &view), PLX_STATUS_OK);

    /* Photo out: every format, padded strides, padding untouched, byte-exact for 8-bit. */
    static uint8_t rgb[W * H * 3];
    for (unsigned i = 0; i < W * H; i++) {
        rgb[3 * i] = (uint8_t)(i * 7), rgb[3 * i + 1] = (uint8_t)(i * 13 + 5), rgb[3 * i + 2] = (uint8_t)(i / 3);
    }
    plx_image photo = {rgb, W, H, W * 3, PLX_PIXEL_FORMAT_RGB8};
    CHECK_STATUS(scene, plx_scene_set_stereo_pair(scene, &photo, &photo), PLX_STATUS_OK);
    enum { PAD = 16 };
    static uint8_t out8[H * (W * 4 + PAD)];
    memset(out8, 0xAB, sizeof out8);
    plx_image_out o = {out8, W, H, W * 4 + PAD, PLX_PIXEL_FORMAT_RGBA8};
    CHECK_STATUS(scene, plx_scene_photo(scene, &o), PLX_STATUS_OK);
    int exact = 1, pad_ok = 1;
    for (unsigned y = 0; y < H; y++) {
        const uint8_t *row = out8 + y * o.stride;
        for (unsigned x = 0; x < W; x++) {
            const uint8_t *s = rgb + 3 * (y * W + x);
            exact &= row[4 * x] == s[0] && row[4 * x + 1] == s[1] && row[4 * x + 2] == s[2] && row[4 * x + 3] == 255;
        }
        for (unsigned p = 0; p < PAD; p++) pad_ok &= row[W * 4 + p] == 0xAB;
    }
    CHECK(exact && pad_ok);
    o.format = PLX_PIXEL_FORMAT_BGRA8;
    CHECK_STATUS(scene, plx_scene_photo(scene, &o), PLX_STATUS_OK);
    CHECK(out8[0] == rgb[2] && out8[2] == rgb[0] && out8[o.stride + 4 * 5 + 1] == rgb[3 * (W + 5) + 1]);
    static uint8_t out3[H * W * 3];
    plx_image_out o3 = {out3, W, H, W * 3, PLX_PIXEL_FORMAT_RGB8};
    CHECK_STATUS(scene, plx_scene_photo(scene, &o3), PLX_STATUS_OK);
    CHECK(memcmp(out3, rgb, sizeof rgb) == 0);
    static float outf[H * (W * 4 + 3)];
    plx_image_out of = {(uint8_t *)outf, W, H, (W * 4 + 3) * sizeof(float), PLX_PIXEL_FORMAT_RGBA_F32};
    CHECK_STATUS(scene, plx_scene_photo(scene, &of), PLX_STATUS_OK);
    double worst = 0;
    for (unsigned y = 0; y < H; y++)
        for (unsigned x = 0; x < W; x++) {
            const float *px = outf + y * (W * 4 + 3) + 4 * x;
            const uint8_t *s = rgb + 3 * (y * W + x);
            for (int c = 0; c < 3; c++) worst = fmax(worst, fabs(px[c] - srgb_to_linear(s[c] / 255.0)));
            worst = fmax(worst, fabs(px[3] - 1.0));
        }
    CHECK(worst < 1e-5);
    static uint16_t outh[H * W * 4];
    plx_image_out oh = {(uint8_t *)outh, W, H, W * 8, PLX_PIXEL_FORMAT_RGBA_F16};
    CHECK_STATUS(scene, plx_scene_photo(scene, &oh), PLX_STATUS_OK);
    CHECK(fabs(half_to_float(outh[4 * 7 + 1]) - srgb_to_linear(rgb[3 * 7 + 1] / 255.0)) < 1e-3);
    static uint8_t gray[W * H];
    plx_image_out og = {gray, W, H, W, PLX_PIXEL_FORMAT_GRAY8};
    CHECK_STATUS(scene, plx_scene_photo(scene, &og), PLX_STATUS_OK);
    {
        const uint8_t *s = rgb + 3 * 10;
        double luma = 0.2126 * srgb_to_linear(s[0] / 255.0) + 0.7152 * srgb_to_linear(s[1] / 255.0) +
                      0.0722 * srgb_to_linear(s[2] / 255.0);
        double enc = luma <= 0.0031308 ? luma * 12.92 : 1.055 * pow(luma, 1 / 2.4) - 0.055;
        CHECK(abs((int)gray[10] - (int)lround(enc * 255)) <= 1);
    }
    /* Bad outputs leave the memory untouched. */
    memset(out8, 0xAB, sizeof out8);
    plx_image_out bad = o;
    bad.width = W - 1;
    CHECK_STATUS(scene, plx_scene_photo(scene, &bad), PLX_STATUS_SIZE_MISMATCH);
    CHECK_MESSAGE(scene, "95x48");
    bad = o, bad.stride = W * 4 - 1;
    CHECK_STATUS(scene, plx_scene_photo(scene, &bad), PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(scene, "stride");
    bad = o, bad.format = 99;
    CHECK_STATUS(scene, plx_scene_photo(scene, &bad), PLX_STATUS_INVALID_ARGUMENT);
    bad = o, bad.data = NULL;
    CHECK_STATUS(scene, plx_scene_photo(scene, &bad), PLX_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(scene, plx_scene_photo(scene, NULL), PLX_STATUS_NULL_ARGUMENT);
    CHECK(out8[0] == 0xAB && out8[sizeof out8 - 1] == 0xAB);
    {
        plx_scene *empty = NULL;
        CHECK_STATUS(ctx, plx_scene_new(ctx, &empty), PLX_STATUS_OK);
        CHECK_STATUS(empty, plx_scene_photo(empty, &o), PLX_STATUS_NOT_AVAILABLE);
        plx_scene_free(empty);
    }

    /* Stereo pair from files: a PNG pair written here, matched like the in-memory one. */
    crc_init();
    /* Unique enough for concurrent runs (plain and ASan builds): time and a stack address. */
    char lpath[96], rpath[96];
    unsigned long tag = (unsigned long)time(NULL) ^ (unsigned long)(uintptr_t)&tag;
    snprintf(lpath, sizeof lpath, "/tmp/plx-hosts-%lx-left.png", tag);
    snprintf(rpath, sizeof rpath, "/tmp/plx-hosts-%lx-right.png", tag);
    CHECK(write_png_gray(lpath, left, W, H) && write_png_gray(rpath, right, W, H));
    CHECK_STATUS(scene, plx_scene_load_stereo_pair(scene, lpath, rpath), PLX_STATUS_OK);
    CHECK_STATUS(scene, plx_scene_disparity(scene, &view), PLX_STATUS_OK);
    CHECK(fabsf(*(const float *)((const uint8_t *)view.data + 24 * view.stride + 60 * 4) - SHIFT) < 0.25f);
    CHECK_STATUS(scene, plx_scene_photo(scene, &og), PLX_STATUS_OK);
    CHECK(memcmp(gray, left, sizeof left) == 0);
    CHECK_STATUS(scene, plx_scene_load_stereo_pair(scene, lpath, "/no/such/right.png"), PLX_STATUS_IO);
    CHECK_MESSAGE(scene, "right.png");
    {
        FILE *f = fopen(rpath, "wb");
        fputs("not an image", f);
        fclose(f);
    }
    CHECK_STATUS(scene, plx_scene_load_stereo_pair(scene, lpath, rpath), PLX_STATUS_FORMAT);
    CHECK_STATUS(scene, plx_scene_load_stereo_pair(scene, NULL, rpath), PLX_STATUS_NULL_ARGUMENT);
    remove(lpath);
    remove(rpath);

    plx_scene_free(scene);
    plx_context_free(ctx);
    TEST_EXIT();
}
