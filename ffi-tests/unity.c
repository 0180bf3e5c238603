/* The Unity rendering-plugin entry points (feature `unity`), called as Unity calls them: a
 * stand-in for Unity's interface table given to UnityPluginLoad, the render-event callback from
 * GetRenderEventFunc run on another thread (Unity's render thread) with event ids registered by
 * plx_unity_set_render_target, then UnityPluginUnload. The scene has no artefact, so the
 * composite is the photo and no GPU is needed (the GPU path is tested in Rust). Built without the
 * feature, the test only says so. */
#include "check.h"

#if defined(PLX_FEATURE_UNITY)
#include <pthread.h>

/* Unity's table: the plugin must keep it and may call it; ours counts the calls. */
static int interface_calls = 0;
static void *get_interface(plx_unity_guid guid) {
    (void)guid;
    interface_calls++;
    return NULL;
}
static void register_interface(plx_unity_guid guid, void *ptr) {
    (void)guid;
    (void)ptr;
    interface_calls++;
}
static void *get_interface_split(uint64_t high, uint64_t low) {
    (void)high;
    (void)low;
    interface_calls++;
    return NULL;
}
static void register_interface_split(uint64_t high, uint64_t low, void *ptr) {
    (void)high;
    (void)low;
    (void)ptr;
    interface_calls++;
}

/* What Unity's render thread does for GL.IssuePluginEvent(GetRenderEventFunc(), id). */
struct issue {
    plx_unity_rendering_event event;
    const int32_t *ids;
    int count;
};
static void *render_thread(void *arg) {
    struct issue *issue = (struct issue *)arg;
    for (int i = 0; i < issue->count; i++) issue->event(issue->ids[i]);
    return NULL;
}
static void issue_on_render_thread(plx_unity_rendering_event event, const int32_t *ids, int count) {
    struct issue issue = {event, ids, count};
    pthread_t thread;
    CHECK(pthread_create(&thread, NULL, render_thread, &issue) == 0);
    CHECK(pthread_join(thread, NULL) == 0);
}

static void check_message(int32_t id, const char *needle) {
    char msg[512];
    size_t needed = 0;
    CHECK_STATUS(NULL, plx_unity_last_event_message(id, msg, sizeof msg, &needed), PLX_STATUS_OK);
    if (strstr(msg, needle) == NULL) {
        fprintf(stderr, "event %d: message \"%s\" lacks \"%s\"\n", (int)id, msg, needle);
        plx_failures++;
    }
    CHECK(needed == strlen(msg) + 1);
}

int main(void) {
    plx_unity_interfaces unity = {get_interface, register_interface, get_interface_split,
                                  register_interface_split};
    CHECK(plx_unity_interfaces_get() == NULL);
    UnityPluginLoad(&unity);
    CHECK(plx_unity_interfaces_get() == &unity);
    plx_unity_rendering_event event = GetRenderEventFunc();
    CHECK(event != NULL);
    if (event == NULL) TEST_EXIT();

    plx_context *ctx = NULL;
    CHECK_STATUS(NULL, plx_context_new(NULL, &ctx), PLX_STATUS_OK);
    plx_scene *scene = NULL;
    CHECK_STATUS(ctx, plx_scene_new(ctx, &scene), PLX_STATUS_OK);
    enum { W = 8, H = 4 };
    uint8_t left[W * H * 3], right[W * H * 3];
    for (int i = 0; i < W * H * 3; i++) left[i] = right[i] = (uint8_t)(i * 29 + 5);
    plx_image l = {left, W, H, W * 3, PLX_PIXEL_FORMAT_RGB8};
    plx_image r = {right, W, H, W * 3, PLX_PIXEL_FORMAT_RGB8};
    CHECK_STATUS(scene, plx_scene_set_stereo_pair(scene, &l, &r), PLX_STATUS_OK);
    /* A second scene without a photo: its event fails, recorded, without harm. */
    plx_scene *empty = NULL;
    CHECK_STATUS(ctx, plx_scene_new(ctx, &empty), PLX_STATUS_OK);

    /* Host buffers as a Unity BGRA32 texture's raw data, and a coverage mask. */
    uint8_t bgra[W * H * 4], never[W * H * 4], small_buf[W * H * 4];
    memset(bgra, 0, sizeof bgra);
    memset(never, 0xAB, sizeof never);
    uint8_t mask[W * H];
    memset(mask, 7, sizeof mask);
    plx_image_out out = {bgra, W, H, W * 4, PLX_PIXEL_FORMAT_BGRA8};
    plx_image_out mask_out = {mask, W, H, W, PLX_PIXEL_FORMAT_GRAY8};
    plx_image_out wrong = {small_buf, W - 1, H, W * 4, PLX_PIXEL_FORMAT_BGRA8};
    plx_image_out untouched = {never, W, H, W * 4, PLX_PIXEL_FORMAT_BGRA8};
    plx_render_options opts;
    CHECK_STATUS(NULL, plx_render_options_init(&opts), PLX_STATUS_OK);
    opts.msaa = 0;

    CHECK_STATUS(NULL, plx_unity_set_render_target(1, scene, &opts, &out, &mask_out),
                 PLX_STATUS_OK);
    CHECK_STATUS(NULL, plx_unity_set_render_target(2, scene, NULL, &wrong, NULL), PLX_STATUS_OK);
    CHECK_STATUS(NULL, plx_unity_set_render_target(3, empty, NULL, &untouched, NULL),
                 PLX_STATUS_OK);
    /* Argument checks: nothing registered for 4. */
    CHECK_STATUS(NULL, plx_unity_set_render_target(4, scene, &opts, NULL, NULL),
                 PLX_STATUS_NULL_ARGUMENT);
    plx_image_out no_data = out;
    no_data.data = NULL;
    CHECK_STATUS(NULL, plx_unity_set_render_target(4, scene, &opts, &no_data, NULL),
                 PLX_STATUS_NULL_ARGUMENT);
    plx_render_options bad = opts;
    bad.size = 2;
    CHECK_STATUS(NULL, plx_unity_set_render_target(4, scene, &bad, &out, NULL),
                 PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(NULL, "plx_render_options_init");

    /* Never ran yet. */
    uint64_t runs = 99;
    CHECK(plx_unity_last_event_status(1, &runs) == PLX_STATUS_NOT_AVAILABLE && runs == 0);
    check_message(1, "");

    /* Unity's render thread runs the events: 1 twice, 2, 3, 4 (never registered), 5. */
    const int32_t ids[] = {1, 2, 3, 4, -5, 1};
    issue_on_render_thread(event, ids, (int)(sizeof ids / sizeof ids[0]));

    /* Event 1: the composite (the photo: no artefact) in BGRA, alpha opaque, mask 0. */
    CHECK(plx_unity_last_event_status(1, &runs) == PLX_STATUS_OK && runs == 2);
    check_message(1, "");
    int same = 1;
    for (int p = 0; p < W * H; p++) {
        same &= bgra[4 * p + 0] == left[3 * p + 2];
        same &= bgra[4 * p + 1] == left[3 * p + 1];
        same &= bgra[4 * p + 2] == left[3 * p + 0];
        same &= bgra[4 * p + 3] == 255;
        same &= mask[p] == 0;
    }
    CHECK(same);
    /* Event 2: a buffer of the wrong size, recorded with the scene's message. */
    CHECK(plx_unity_last_event_status(2, &runs) == PLX_STATUS_SIZE_MISMATCH && runs == 1);
    check_message(2, "7x4");
    /* Event 3: a scene without a photo; its buffer is untouched. */
    CHECK(plx_unity_last_event_status(3, NULL) == PLX_STATUS_NOT_AVAILABLE);
    check_message(3, "stereo pair");
    for (size_t i = 0; i < sizeof never; i++) CHECK(never[i] == 0xAB);
    /* Events 4 and -5 were never registered: an error recorded, no crash. */
    CHECK(plx_unity_last_event_status(4, &runs) == PLX_STATUS_INVALID_ARGUMENT && runs == 1);
    check_message(4, "event id 4");
    CHECK(plx_unity_last_event_status(-5, &runs) == PLX_STATUS_INVALID_ARGUMENT && runs == 1);
    check_message(-5, "event id -5");
    /* Message buffer checks. */
    size_t needed = 0;
    CHECK_STATUS(NULL, plx_unity_last_event_message(2, NULL, 0, &needed), PLX_STATUS_OK);
    CHECK(needed > 1);
    char tiny[4];
    CHECK_STATUS(NULL, plx_unity_last_event_message(2, tiny, sizeof tiny, NULL), PLX_STATUS_OK);
    CHECK(strlen(tiny) == 3);
    CHECK_STATUS(NULL, plx_unity_last_event_message(2, NULL, 8, NULL), PLX_STATUS_NULL_ARGUMENT);

    /* Removing a target: its event then fails as unregistered. */
    CHECK_STATUS(NULL, plx_unity_set_render_target(1, NULL, NULL, NULL, NULL), PLX_STATUS_OK);
    const int32_t again[] = {1};
    issue_on_render_thread(event, again, 1);
    CHECK(plx_unity_last_event_status(1, &runs) == PLX_STATUS_INVALID_ARGUMENT && runs == 3);

    /* The scene stays usable from the main thread. */
    CHECK_STATUS(scene, plx_scene_photo(scene, &out), PLX_STATUS_OK);

    /* Unload forgets the table, the targets and the outcomes. */
    UnityPluginUnload();
    CHECK(plx_unity_interfaces_get() == NULL);
    CHECK(plx_unity_last_event_status(2, &runs) == PLX_STATUS_NOT_AVAILABLE && runs == 0);
    /* Unity may load the plugin again. */
    UnityPluginLoad(&unity);
    CHECK(plx_unity_interfaces_get() == &unity);
    const int32_t after[] = {2};
    GetRenderEventFunc()(after[0]);
    CHECK(plx_unity_last_event_status(2, &runs) == PLX_STATUS_INVALID_ARGUMENT && runs == 1);
    UnityPluginUnload();
    /* The plugin needs none of Unity's interfaces. */
    CHECK(interface_calls == 0);

    plx_scene_free(empty);
    plx_scene_free(scene);
    plx_context_free(ctx);
    TEST_EXIT();
}

#else
int main(void) {
    printf("unity.c: skipped, the library was built without the `unity` feature\n");
    return plx_failures;
}
#endif
