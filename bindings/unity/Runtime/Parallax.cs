// Parallax C# API: a small idiomatic wrapper over the P/Invoke declarations in Parallax.Native.cs.
//
// - Context and Scene own SafeHandles (ContextHandle, SceneHandle): Dispose them, or let the
//   finalizer free them.
// - Every failing call throws ParallaxException, carrying the PlxStatus and the library's message.
// - Views into library memory (disparity, depth, mesh, surfaces) are copied into managed arrays,
//   so they stay valid after the scene changes.
// - Images are rows top first (Parallax's convention; Unity textures are bottom-up: see
//   ParallaxCompositor in the Unity package, which flips them).
// - Thread safety is that of the C API: a Context may be shared by threads; a Scene is used by
//   one thread at a time (Scene.Clone gives another scene sharing the reconstruction).
using System;
using System.Collections.Generic;
using System.Runtime.InteropServices;
using System.Text;
#if UNITY_5_3_OR_NEWER
// IL2CPP (iOS, consoles) compiles callbacks from native code only when marked with this one.
using MonoPInvokeCallbackAttribute = AOT.MonoPInvokeCallbackAttribute;
#endif

namespace Parallax
{
    /// <summary>A failed Parallax call: its status and the library's message.</summary>
    public class ParallaxException : Exception
    {
        public ParallaxException(PlxStatus status, string message) : base(message)
        {
            Status = status;
        }

        public ParallaxException(PlxStatus status, string message, Exception inner) : base(message, inner)
        {
            Status = status;
        }

        /// <summary>The plx_status the call returned.</summary>
        public PlxStatus Status { get; private set; }
    }

    /// <summary>NUL-terminated UTF-8 strings across the boundary.</summary>
    public static class Utf8
    {
        /// <summary>The UTF-8 bytes of <paramref name="text"/> and a terminating NUL (null for null).</summary>
        public static byte[] Encode(string text)
        {
            if (text == null)
                return null;
            byte[] body = Encoding.UTF8.GetBytes(text);
            byte[] z = new byte[body.Length + 1];
            Array.Copy(body, z, body.Length);
            return z;
        }

        /// <summary>The string at a NUL-terminated UTF-8 pointer ("" for NULL).</summary>
        public static string Decode(IntPtr text)
        {
            if (text == IntPtr.Zero)
                return "";
            int n = 0;
            while (Marshal.ReadByte(text, n) != 0)
                n++;
            byte[] bytes = new byte[n];
            Marshal.Copy(text, bytes, 0, n);
            return Encoding.UTF8.GetString(bytes);
        }

        /// <summary>Reads a string out of a snprintf-like C function fill(buf, len, out needed).</summary>
        internal static string Read(Func<byte[], UIntPtr, PlxStatus> fill, Func<UIntPtr> needed, SafeHandle owner)
        {
            Errors.Check(fill(null, UIntPtr.Zero), owner);
            int size = (int)needed();
            if (size <= 1)
                return "";
            byte[] buf = new byte[size];
            Errors.Check(fill(buf, (UIntPtr)size), owner);
            return Encoding.UTF8.GetString(buf, 0, size - 1);
        }
    }

    internal static class Errors
    {
        /// <summary>The last error message of a handle (null = the global one).</summary>
        internal static string LastMessage(SafeHandle handle)
        {
            bool added = false;
            try
            {
                IntPtr raw = IntPtr.Zero;
                if (handle != null && !handle.IsInvalid && !handle.IsClosed)
                {
                    handle.DangerousAddRef(ref added);
                    raw = handle.DangerousGetHandle();
                }
                UIntPtr needed;
                if (Native.plx_last_error_message(raw, null, UIntPtr.Zero, out needed) != PlxStatus.Ok || (ulong)needed <= 1)
                    return "";
                byte[] buf = new byte[(int)needed];
                Native.plx_last_error_message(raw, buf, (UIntPtr)buf.Length, out needed);
                return Encoding.UTF8.GetString(buf, 0, buf.Length - 1);
            }
            finally
            {
                if (added)
                    handle.DangerousRelease();
            }
        }

        internal static void Check(PlxStatus status, SafeHandle handle)
        {
            if (status == PlxStatus.Ok)
                return;
            string message = LastMessage(handle);
            if (message.Length == 0)
                message = Library.StatusString(status);
            throw new ParallaxException(status, message);
        }
    }

    /// <summary>Process-wide functions: version, status strings, the log callback.</summary>
    public static class Library
    {
        /// <summary>The library version, e.g. "0.1.0".</summary>
        public static string Version { get { return Utf8.Decode(Native.plx_version()); } }

        /// <summary>A static description of a status.</summary>
        public static string StatusString(PlxStatus status)
        {
            return Utf8.Decode(Native.plx_status_str((uint)status));
        }

        static readonly object logLock = new object();
        static Action<PlxLogLevel, string> logCallback;
        // Kept alive for the process: the C library may call it from any thread until replaced.
        static readonly PlxLogFn logTrampoline = LogTrampoline;

        [MonoPInvokeCallback(typeof(PlxLogFn))]
        static void LogTrampoline(IntPtr userData, uint level, IntPtr message)
        {
            try
            {
                Action<PlxLogLevel, string> callback = logCallback;
                if (callback != null)
                    callback((PlxLogLevel)level, Utf8.Decode(message));
            }
            catch (Exception)
            {
                // Must not unwind into native code.
            }
        }

        /// <summary>
        /// The process-wide log callback, up to <paramref name="maxLevel"/>; null removes it. It
        /// may run on any thread that calls Parallax; exceptions it throws are swallowed. In the
        /// Unity editor the native library survives domain reloads: remove the callback before one
        /// (e.g. in OnDestroy or AssemblyReloadEvents.beforeAssemblyReload).
        /// </summary>
        public static void SetLogCallback(Action<PlxLogLevel, string> callback, PlxLogLevel maxLevel = PlxLogLevel.Warn)
        {
            lock (logLock)
            {
                if (callback == null)
                {
                    Errors.Check(Native.plx_set_log_callback(null, IntPtr.Zero, (uint)maxLevel), null);
                    logCallback = null;
                }
                else
                {
                    logCallback = callback;
                    Errors.Check(Native.plx_set_log_callback(logTrampoline, IntPtr.Zero, (uint)maxLevel), null);
                }
            }
        }
    }

    /// <summary>What scenes share (size caps, the lazily opened GPU); owns a plx_context. Thread-safe.</summary>
    public sealed class Context : IDisposable
    {
        /// <summary>A context with the default options.</summary>
        public Context() : this(PlxContextOptions.CreateDefault()) { }

        /// <summary>A context with a pixel cap (0 = default) and a GPU adapter name substring (null = any).</summary>
        public Context(ulong maxImagePixels, string adapterName)
            : this(WithOverrides(maxImagePixels), adapterName) { }

        /// <summary>A context with <paramref name="options"/> (start from PlxContextOptions.CreateDefault()).</summary>
        public Context(PlxContextOptions options) : this(options, null) { }

        Context(PlxContextOptions options, string adapterName)
        {
            byte[] name = Utf8.Encode(adapterName);
            GCHandle pin = name != null ? GCHandle.Alloc(name, GCHandleType.Pinned) : default(GCHandle);
            try
            {
                if (name != null)
                    options.AdapterName = pin.AddrOfPinnedObject();
                ContextHandle h;
                PlxStatus status = Native.plx_context_new(ref options, out h);
                if (status != PlxStatus.Ok)
                {
                    h.Dispose();
                    Errors.Check(status, null);
                }
                Handle = h;
            }
            finally
            {
                if (pin.IsAllocated)
                    pin.Free();
            }
        }

        static PlxContextOptions WithOverrides(ulong maxImagePixels)
        {
            PlxContextOptions o = PlxContextOptions.CreateDefault();
            if (maxImagePixels > 0)
                o.MaxImagePixels = maxImagePixels;
            return o;
        }

        /// <summary>The owned C handle.</summary>
        public ContextHandle Handle { get; private set; }

        public void Dispose() { Handle.Dispose(); }
    }

    /// <summary>A grid of floats copied out of the library (disparity, confidence, depth, depth buffers).</summary>
    public sealed class FloatGrid
    {
        public int Width;
        public int Height;
        /// <summary>Row-major, top row first, Width values per row.</summary>
        public float[] Data;

        public float this[int x, int y] { get { return Data[y * Width + x]; } }

        internal static FloatGrid Copy(PlxFloatView v)
        {
            FloatGrid g = new FloatGrid();
            g.Width = (int)v.Width;
            g.Height = (int)v.Height;
            g.Data = new float[(long)g.Width * g.Height];
            long stride = (long)(ulong)v.Stride;
            for (int y = 0; y < g.Height; y++)
                Marshal.Copy(new IntPtr(v.Data.ToInt64() + y * stride), g.Data, y * g.Width, g.Width);
            return g;
        }
    }

    /// <summary>The scene mesh (camera frame, metres), copied out of the library.</summary>
    public sealed class Mesh
    {
        public float[] Positions; // 3 per vertex
        public float[] Normals;   // 3 per vertex
        public float[] Tangents;  // 4 per vertex
        public float[] Uvs;       // 2 per vertex
        public int[] Indices;     // 3 per triangle (uint32 in C; below 2^31 here)
        public int VertexCount { get { return Positions.Length / 3; } }
        public int TriangleCount { get { return Indices.Length / 3; } }
    }

    /// <summary>Bounding boxes of an artefact, metres (x, y, z each).</summary>
    public sealed class Bounds
    {
        public float[] LocalMin = new float[3], LocalMax = new float[3];
        public float[] WorldMin = new float[3], WorldMax = new float[3];
    }

    /// <summary>The left camera: intrinsics and clip range in metres.</summary>
    public struct CameraInfo
    {
        public PlxCamera Intrinsics;
        public float Near;
        public float Far;
    }

    /// <summary>The main light as AR platforms give it.</summary>
    public struct MainLight
    {
        /// <summary>Unit vector from the scene towards the light.</summary>
        public float[] Direction;
        public float[] Rgb;
    }

    /// <summary>A photo's reconstruction and what is inserted into it; owns a plx_scene. One thread at a time.</summary>
    public sealed class Scene : IDisposable
    {
        sealed class ProgressHolder
        {
            public Func<string, float, bool> Callback;
            public Exception Error;
        }

        static readonly PlxProgressFn progressTrampoline = ProgressTrampoline;

        /// <summary>An empty scene in <paramref name="context"/> (which may be disposed first).</summary>
        public Scene(Context context)
        {
            SceneHandle h;
            PlxStatus status = Native.plx_scene_new(context.Handle, out h);
            if (status != PlxStatus.Ok)
            {
                h.Dispose();
                Errors.Check(status, context.Handle);
            }
            Handle = h;
        }

        Scene(SceneHandle handle) { Handle = handle; }

        /// <summary>The owned C handle.</summary>
        public SceneHandle Handle { get; private set; }

        public void Dispose() { Handle.Dispose(); }

        void Check(PlxStatus status)
        {
            if (status == PlxStatus.Cancelled && Handle.Progress.IsAllocated)
            {
                ProgressHolder holder = (ProgressHolder)Handle.Progress.Target;
                Exception e = holder.Error;
                if (e != null)
                {
                    holder.Error = null;
                    throw new ParallaxException(PlxStatus.Cancelled, "the progress callback threw: " + e.Message, e);
                }
            }
            Errors.Check(status, Handle);
        }

        /// <summary>A new scene sharing this one's inputs and computed products (plx_scene_clone).</summary>
        public Scene Clone()
        {
            SceneHandle copy;
            PlxStatus status = Native.plx_scene_clone(Handle, out copy);
            if (status != PlxStatus.Ok)
            {
                copy.Dispose();
                Check(status);
            }
            Scene s = new Scene(copy);
            // The C copy points at this scene's callback holder: give it its own (or none).
            Func<string, float, bool> callback = null;
            if (Handle.Progress.IsAllocated)
                callback = ((ProgressHolder)Handle.Progress.Target).Callback;
            s.SetProgressCallback(callback);
            return s;
        }

        // ---- inputs -----------------------------------------------------------------------

        /// <summary>The rectified stereo pair: two images of <paramref name="format"/>, rows top first,
        /// <paramref name="stride"/> bytes apart (0 = tightly packed).</summary>
        public void SetStereoPair(byte[] left, byte[] right, int width, int height, PlxPixelFormat format, int stride = 0)
        {
            if (stride == 0)
                stride = width * BytesPerPixel(format);
            GCHandle l = GCHandle.Alloc(left, GCHandleType.Pinned);
            GCHandle r = GCHandle.Alloc(right, GCHandleType.Pinned);
            try
            {
                PlxImage li = Image(l.AddrOfPinnedObject(), width, height, stride, format);
                PlxImage ri = Image(r.AddrOfPinnedObject(), width, height, stride, format);
                CheckLength(left, stride, height, width, format, "left");
                CheckLength(right, stride, height, width, format, "right");
                Check(Native.plx_scene_set_stereo_pair(Handle, ref li, ref ri));
            }
            finally
            {
                l.Free();
                r.Free();
            }
        }

        /// <summary>The photo alone (rows top first, <paramref name="stride"/> bytes apart, 0 = tightly
        /// packed), for a host that gives its own depth (SetDepth): lights and composites use it.</summary>
        public void SetPhoto(byte[] photo, int width, int height, PlxPixelFormat format, int stride = 0)
        {
            if (stride == 0)
                stride = width * BytesPerPixel(format);
            GCHandle p = GCHandle.Alloc(photo, GCHandleType.Pinned);
            try
            {
                PlxImage pi = Image(p.AddrOfPinnedObject(), width, height, stride, format);
                CheckLength(photo, stride, height, width, format, "photo");
                Check(Native.plx_scene_set_photo(Handle, ref pi));
            }
            finally
            {
                p.Free();
            }
        }

        /// <summary>Reads the pair from image files (PNG, JPEG, EXR, HDR).</summary>
        public void LoadStereoPair(string leftPath, string rightPath)
        {
            Check(Native.plx_scene_load_stereo_pair(Handle, Utf8.Encode(leftPath), Utf8.Encode(rightPath)));
        }

        public void SetCalibration(PlxCalibration calibration)
        {
            Check(Native.plx_scene_set_calibration(Handle, ref calibration));
        }

        /// <summary>Focal length in pixels and baseline in metres, principal point at the photo's centre.</summary>
        public void SetCalibration(double focalPx, double baselineM)
        {
            int w, h;
            PhotoSize(out w, out h);
            PlxCalibration c = new PlxCalibration();
            c.FocalPx = focalPx;
            c.BaselineM = baselineM;
            c.Cx = w / 2.0;
            c.Cy = h / 2.0;
            SetCalibration(c);
        }

        public void SetStereoOptions(PlxStereoOptions options)
        {
            Check(Native.plx_scene_set_stereo_options(Handle, ref options));
        }

        public void ResetStereoOptions() { Check(Native.plx_scene_set_stereo_options(Handle, IntPtr.Zero)); }

        /// <summary>The host's own depth in metres (rows top first), optional confidence and camera.</summary>
        public void SetDepth(float[] depth, int width, int height, float[] confidence = null, PlxCamera? camera = null)
        {
            UIntPtr stride = (UIntPtr)(width * 4);
            UIntPtr cstride = confidence != null ? stride : UIntPtr.Zero;
            if (depth == null || depth.Length < width * height)
                throw new ArgumentException("depth holds fewer than width * height values");
            if (confidence != null && confidence.Length < width * height)
                throw new ArgumentException("confidence holds fewer than width * height values");
            if (camera.HasValue)
            {
                PlxCamera c = camera.Value;
                Check(Native.plx_scene_set_depth(Handle, depth, (uint)width, (uint)height, stride, confidence, cstride, ref c));
            }
            else
            {
                Check(Native.plx_scene_set_depth(Handle, depth, (uint)width, (uint)height, stride, confidence, cstride, IntPtr.Zero));
            }
        }

        public void ClearDepth() { Check(Native.plx_scene_clear_depth(Handle)); }

        /// <summary>Clip range in metres; (0, 0) = automatic.</summary>
        public void SetClip(float near, float far) { Check(Native.plx_scene_set_clip(Handle, near, far)); }

        public void SetMeshOptions(PlxMeshOptions options) { Check(Native.plx_scene_set_mesh_options(Handle, ref options)); }

        public void ResetMeshOptions() { Check(Native.plx_scene_set_mesh_options(Handle, IntPtr.Zero)); }

        /// <summary>Progress: (stage, fraction 0 or 1) returns true to go on, false to cancel (the call
        /// then throws ParallaxException with PlxStatus.Cancelled). null removes it.</summary>
        public void SetProgressCallback(Func<string, float, bool> callback)
        {
            GCHandle next = default(GCHandle);
            if (callback != null)
            {
                ProgressHolder holder = new ProgressHolder();
                holder.Callback = callback;
                next = GCHandle.Alloc(holder);
            }
            PlxStatus status = callback != null
                ? Native.plx_scene_set_progress_callback(Handle, progressTrampoline, GCHandle.ToIntPtr(next))
                : Native.plx_scene_set_progress_callback(Handle, null, IntPtr.Zero);
            if (status != PlxStatus.Ok)
            {
                if (next.IsAllocated)
                    next.Free();
                Check(status);
            }
            if (Handle.Progress.IsAllocated)
                Handle.Progress.Free();
            Handle.Progress = next;
        }

        [MonoPInvokeCallback(typeof(PlxProgressFn))]
        static int ProgressTrampoline(IntPtr userData, IntPtr stage, float fraction)
        {
            ProgressHolder holder = null;
            try
            {
                holder = (ProgressHolder)GCHandle.FromIntPtr(userData).Target;
                return holder.Callback(Utf8.Decode(stage), fraction) ? 0 : 1;
            }
            catch (Exception e)
            {
                if (holder != null)
                    holder.Error = e;
                return 1;
            }
        }

        // ---- products ---------------------------------------------------------------------

        public FloatGrid Disparity()
        {
            PlxFloatView v;
            Check(Native.plx_scene_disparity(Handle, out v));
            return FloatGrid.Copy(v);
        }

        public FloatGrid Confidence()
        {
            PlxFloatView v;
            Check(Native.plx_scene_confidence(Handle, out v));
            return FloatGrid.Copy(v);
        }

        public FloatGrid Depth()
        {
            PlxFloatView v;
            Check(Native.plx_scene_depth(Handle, out v));
            return FloatGrid.Copy(v);
        }

        /// <summary>Depth for a host depth buffer; clip (0, 0) = the camera's.</summary>
        public FloatGrid DepthBuffer(PlxDepthEncoding encoding, float near = 0, float far = 0)
        {
            PlxFloatView v;
            Check(Native.plx_scene_depth_buffer(Handle, (uint)encoding, near, far, out v));
            return FloatGrid.Copy(v);
        }

        public CameraInfo Camera()
        {
            CameraInfo c;
            Check(Native.plx_scene_camera(Handle, out c.Intrinsics, out c.Near, out c.Far));
            return c;
        }

        public Mesh Mesh()
        {
            PlxMeshView v;
            Check(Native.plx_scene_mesh(Handle, out v));
            int n = (int)(ulong)v.VertexCount;
            Mesh m = new Mesh();
            m.Positions = Floats(v.Positions, 3 * n);
            m.Normals = Floats(v.Normals, 3 * n);
            m.Tangents = Floats(v.Tangents, 4 * n);
            m.Uvs = Floats(v.Uvs, 2 * n);
            m.Indices = new int[(int)(ulong)v.IndexCount];
            if (m.Indices.Length > 0)
                Marshal.Copy(v.Indices, m.Indices, 0, m.Indices.Length);
            return m;
        }

        /// <summary>The support surfaces, largest first.</summary>
        public PlxSurface[] Surfaces()
        {
            UIntPtr count;
            IntPtr list;
            Check(Native.plx_scene_surfaces(Handle, out count, out list));
            PlxSurface[] s = new PlxSurface[(int)(ulong)count];
            int size = Marshal.SizeOf(typeof(PlxSurface));
            for (int i = 0; i < s.Length; i++)
                s[i] = (PlxSurface)Marshal.PtrToStructure(new IntPtr(list.ToInt64() + (long)i * size), typeof(PlxSurface));
            return s;
        }

        /// <summary>The gravity "up" (unit vector, camera frame).</summary>
        public float[] Up()
        {
            float[] v = new float[3];
            Check(Native.plx_scene_up(Handle, v));
            return v;
        }

        /// <summary>The host's gravity up (3 floats in Parallax's camera frame: +X right, +Y up,
        /// -Z forward; any length), e.g. an IMU's gravity negated. null = back to the estimate.</summary>
        public void SetUp(float[] up)
        {
            if (up != null && up.Length != 3)
                throw new ArgumentException("up takes 3 floats");
            Check(Native.plx_scene_set_up(Handle, up));
        }

        public PlxHit Pick(float x, float y)
        {
            PlxHit h;
            Check(Native.plx_scene_pick(Handle, x, y, out h));
            return h;
        }

        /// <summary>A model → world transform (16 floats, column-major) standing an object on the pixel.</summary>
        public float[] Place(float x, float y, float sizeM, float yawDeg = 0)
        {
            float[] m = new float[16];
            Check(Native.plx_scene_place(Handle, x, y, sizeM, yawDeg, m));
            return m;
        }

        public float[] PlaceOnRay(float[] origin, float[] direction, float sizeM, float yawDeg = 0)
        {
            float[] m = new float[16];
            Check(Native.plx_scene_place_on_ray(Handle, origin, direction, sizeM, yawDeg, m));
            return m;
        }

        /// <summary>The photo's size (cheap: decodes and computes nothing).</summary>
        public void PhotoSize(out int width, out int height)
        {
            uint w, h;
            Check(Native.plx_scene_photo_size(Handle, out w, out h));
            width = (int)w;
            height = (int)h;
        }

        /// <summary>Writes the photo into a host image of its size.</summary>
        public void Photo(byte[] output, int width, int height, PlxPixelFormat format, int stride = 0)
        {
            if (stride == 0)
                stride = width * BytesPerPixel(format);
            CheckLength(output, stride, height, width, format, "output");
            GCHandle pin = GCHandle.Alloc(output, GCHandleType.Pinned);
            try
            {
                PlxImageOut o = ImageOut(pin.AddrOfPinnedObject(), width, height, stride, format);
                Check(Native.plx_scene_photo(Handle, ref o));
            }
            finally
            {
                pin.Free();
            }
        }

        /// <summary>The JSON report of the last call that computed or fetched a product.</summary>
        public string Report()
        {
            UIntPtr needed = UIntPtr.Zero;
            return Utf8.Read(
                (buf, len) => Native.plx_scene_report(Handle, buf, len, out needed),
                () => needed, Handle);
        }

        // ---- artefacts --------------------------------------------------------------------

        /// <summary>Loads a .gltf/.glb file with an optional column-major transform; returns its id.</summary>
        public uint AddArtefactPath(string path, float[] transform = null)
        {
            CheckMatrix(transform, true);
            uint id;
            Check(Native.plx_scene_add_artefact_path(Handle, Utf8.Encode(path), transform, out id));
            return id;
        }

        /// <summary>Loads a GLB (or self-contained .gltf) from memory; returns its id.</summary>
        public uint AddArtefactMemory(byte[] bytes, float[] transform = null)
        {
            CheckMatrix(transform, true);
            uint id;
            Check(Native.plx_scene_add_artefact_memory(Handle, bytes, (UIntPtr)(bytes != null ? bytes.Length : 0), transform, out id));
            return id;
        }

        public void SetArtefactTransform(uint id, float[] transform)
        {
            CheckMatrix(transform, false);
            Check(Native.plx_scene_set_artefact_transform(Handle, id, transform));
        }

        public void SetArtefactFlags(uint id, bool visible, bool castsShadow, bool receivesShadow)
        {
            Check(Native.plx_scene_set_artefact_flags(Handle, id, visible ? 1u : 0u, castsShadow ? 1u : 0u, receivesShadow ? 1u : 0u));
        }

        public void RemoveArtefact(uint id) { Check(Native.plx_scene_remove_artefact(Handle, id)); }

        public Bounds ArtefactBounds(uint id)
        {
            Bounds b = new Bounds();
            Check(Native.plx_artefact_bounds(Handle, id, b.LocalMin, b.LocalMax, b.WorldMin, b.WorldMax));
            return b;
        }

        /// <summary>Stands artefact <paramref name="id"/> on the surface under pixel (x, y), its largest
        /// side <paramref name="sizeM"/> metres, turned by <paramref name="yawDeg"/>; returns its transform.</summary>
        public float[] PlaceArtefact(uint id, float x, float y, float sizeM, float yawDeg = 0)
        {
            float[] m = new float[16];
            Check(Native.plx_scene_place_artefact(Handle, id, x, y, sizeM, yawDeg, m));
            return m;
        }

        /// <summary>The loader's warnings for <paramref name="id"/>, one per element.</summary>
        public string[] ArtefactWarnings(uint id)
        {
            UIntPtr needed = UIntPtr.Zero, count;
            string all = Utf8.Read(
                (buf, len) => Native.plx_scene_artefact_warnings(Handle, id, buf, len, out needed, out count),
                () => needed, Handle);
            return all.Length == 0 ? new string[0] : all.Split('\n');
        }

        // ---- lights -----------------------------------------------------------------------

        /// <summary>The lights in use (the host's, else the estimated ones).</summary>
        public PlxLight[] Lights()
        {
            UIntPtr count;
            Check(Native.plx_scene_lights(Handle, null, UIntPtr.Zero, out count));
            PlxLight[] lights = new PlxLight[(int)(ulong)count];
            for (int i = 0; i < lights.Length; i++)
            {
                lights[i].Position = new float[3];
                lights[i].Direction = new float[3];
                lights[i].Intensity = new float[3];
            }
            if (lights.Length > 0)
                Check(Native.plx_scene_lights(Handle, lights, (UIntPtr)lights.Length, out count));
            return lights;
        }

        /// <summary>Replaces the estimated lights (an empty array: no direct light).</summary>
        public void SetLights(PlxLight[] lights)
        {
            foreach (PlxLight l in lights)
                if (l.Position == null || l.Direction == null || l.Intensity == null ||
                    l.Position.Length != 3 || l.Direction.Length != 3 || l.Intensity.Length != 3)
                    throw new ArgumentException("every PlxLight needs Position, Direction and Intensity of 3 floats");
            Check(Native.plx_scene_set_lights(Handle, lights.Length > 0 ? lights : null, (UIntPtr)lights.Length));
        }

        public void ResetLights() { Check(Native.plx_scene_reset_lights(Handle)); }

        public MainLight MainLight()
        {
            MainLight m;
            m.Direction = new float[3];
            m.Rgb = new float[3];
            Check(Native.plx_scene_main_light(Handle, m.Direction, m.Rgb));
            return m;
        }

        /// <summary>The ambient light: 27 floats (nine RGB SH coefficients, ARCore order).</summary>
        public float[] Sh9()
        {
            float[] sh = new float[27];
            Check(Native.plx_scene_sh9(Handle, sh));
            return sh;
        }

        /// <summary>Replaces the estimated ambient light (27 floats); null = back to the estimate.</summary>
        public void SetSh9(float[] sh9)
        {
            if (sh9 != null && sh9.Length != 27)
                throw new ArgumentException("SH9 takes 27 floats");
            Check(Native.plx_scene_set_sh9(Handle, sh9));
        }

        /// <summary>Where the objects will go (3 floats, camera frame, metres): the estimated
        /// environment is built around it. null = back to the default point.</summary>
        public void SetInsertionPoint(float[] point)
        {
            if (point != null && point.Length != 3)
                throw new ArgumentException("an insertion point takes 3 floats");
            Check(Native.plx_scene_set_insertion_point(Handle, point));
        }

        /// <summary>The host's equirectangular environment (twice as wide as high, rows top first).</summary>
        public void SetEnvironmentEquirect(byte[] pixels, int width, int height, PlxPixelFormat format, int stride = 0)
        {
            if (stride == 0)
                stride = width * BytesPerPixel(format);
            CheckLength(pixels, stride, height, width, format, "pixels");
            GCHandle pin = GCHandle.Alloc(pixels, GCHandleType.Pinned);
            try
            {
                PlxImage image = Image(pin.AddrOfPinnedObject(), width, height, stride, format);
                Check(Native.plx_scene_set_environment_equirect(Handle, ref image));
            }
            finally
            {
                pin.Free();
            }
        }

        /// <summary>Edge length in texels of each face of the environment cube.</summary>
        public int EnvironmentCubeSize()
        {
            uint size;
            Check(Native.plx_scene_environment_cube_size(Handle, out size));
            return (int)size;
        }

        /// <summary>Face <paramref name="face"/> (0 +X, 1 -X, 2 +Y, 3 -Y, 4 +Z, 5 -Z; GPU array-layer
        /// order, row 0 at the top) of the environment cube, linear radiance relative to the photo's
        /// white, as EnvironmentCubeSize() squared pixels of <paramref name="format"/> (RgbaF16 for a
        /// GPU's RGBA16F cube).</summary>
        public byte[] EnvironmentCubeFace(int face, PlxPixelFormat format = PlxPixelFormat.RgbaF16)
        {
            int size = EnvironmentCubeSize();
            int stride = size * BytesPerPixel(format);
            byte[] pixels = new byte[stride * size];
            GCHandle pin = GCHandle.Alloc(pixels, GCHandleType.Pinned);
            try
            {
                PlxImageOut o = ImageOut(pin.AddrOfPinnedObject(), size, size, stride, format);
                Check(Native.plx_scene_environment_cube_face(Handle, (uint)face, ref o));
            }
            finally
            {
                pin.Free();
            }
            return pixels;
        }

        /// <summary>Back to the estimated environment.</summary>
        public void ResetEnvironment() { Check(Native.plx_scene_set_environment_equirect(Handle, IntPtr.Zero)); }

        // ---- composite --------------------------------------------------------------------

        /// <summary>Renders the composite into <paramref name="output"/> (the photo's size, rows top
        /// first, <paramref name="format"/>) and, when <paramref name="mask"/> is not null, the artefacts'
        /// coverage in [0, 1] (width * height floats). options null = the defaults.</summary>
        public void Render(byte[] output, int width, int height, PlxPixelFormat format = PlxPixelFormat.Rgba8,
                           PlxRenderOptions? options = null, float[] mask = null, int stride = 0)
        {
            if (stride == 0)
                stride = width * BytesPerPixel(format);
            CheckLength(output, stride, height, width, format, "output");
            if (mask != null && mask.Length < width * height)
                throw new ArgumentException("mask holds fewer than width * height floats");
            GCHandle pin = GCHandle.Alloc(output, GCHandleType.Pinned);
            GCHandle maskPin = mask != null ? GCHandle.Alloc(mask, GCHandleType.Pinned) : default(GCHandle);
            try
            {
                PlxImageOut o = ImageOut(pin.AddrOfPinnedObject(), width, height, stride, format);
                PlxRenderOptions opts = options.HasValue ? options.Value : PlxRenderOptions.CreateDefault();
                if (mask != null)
                {
                    PlxImageOut m = ImageOut(maskPin.AddrOfPinnedObject(), width, height, width * 4, PlxPixelFormat.GrayF32);
                    Check(Native.plx_scene_render(Handle, ref opts, ref o, ref m));
                }
                else
                {
                    Check(Native.plx_scene_render(Handle, ref opts, ref o, IntPtr.Zero));
                }
            }
            finally
            {
                pin.Free();
                if (maskPin.IsAllocated)
                    maskPin.Free();
            }
        }

        /// <summary>The composite as RGBA8 (sRGB, alpha 255), width * height * 4 bytes, rows top first.</summary>
        public byte[] Render(PlxRenderOptions? options = null)
        {
            int w, h;
            PhotoSize(out w, out h);
            byte[] rgba = new byte[w * h * 4];
            Render(rgba, w, h, PlxPixelFormat.Rgba8, options);
            return rgba;
        }

        // ---- helpers ----------------------------------------------------------------------

        /// <summary>Bytes per pixel of a format.</summary>
        public static int BytesPerPixel(PlxPixelFormat format)
        {
            switch (format)
            {
                case PlxPixelFormat.Gray8: return 1;
                case PlxPixelFormat.Rgb8: return 3;
                case PlxPixelFormat.Rgba8: return 4;
                case PlxPixelFormat.Bgra8: return 4;
                case PlxPixelFormat.GrayF32: return 4;
                case PlxPixelFormat.RgbF32: return 12;
                case PlxPixelFormat.RgbaF16: return 8;
                case PlxPixelFormat.RgbaF32: return 16;
                default: throw new ArgumentException("unknown pixel format " + (uint)format);
            }
        }

        static void CheckLength(byte[] buffer, int stride, int height, int width, PlxPixelFormat format, string name)
        {
            if (buffer == null)
                throw new ArgumentNullException(name);
            if (width <= 0 || height <= 0)
                throw new ArgumentException(name + ": width and height must be > 0");
            long needed = (long)stride * (height - 1) + (long)width * BytesPerPixel(format);
            if (stride < width * BytesPerPixel(format) || buffer.Length < needed)
                throw new ArgumentException(name + ": " + buffer.Length + " bytes cannot hold " + width + "x" + height
                    + " pixels of " + format + " with stride " + stride);
        }

        static void CheckMatrix(float[] m, bool nullable)
        {
            if (m == null && nullable)
                return;
            if (m == null || m.Length != 16)
                throw new ArgumentException("a transform is 16 floats, column-major");
        }

        static PlxImage Image(IntPtr data, int width, int height, int stride, PlxPixelFormat format)
        {
            PlxImage i;
            i.Data = data;
            i.Width = (uint)width;
            i.Height = (uint)height;
            i.Stride = (UIntPtr)stride;
            i.Format = (uint)format;
            return i;
        }

        static PlxImageOut ImageOut(IntPtr data, int width, int height, int stride, PlxPixelFormat format)
        {
            PlxImageOut i;
            i.Data = data;
            i.Width = (uint)width;
            i.Height = (uint)height;
            i.Stride = (UIntPtr)stride;
            i.Format = (uint)format;
            return i;
        }

        static float[] Floats(IntPtr data, int n)
        {
            float[] a = new float[n];
            if (n > 0)
                Marshal.Copy(data, a, 0, n);
            return a;
        }
    }

    /// <summary>
    /// Unity's render thread (a native library built with the `unity` feature): registers what a
    /// render event renders, for GL.IssuePluginEvent(UnityRenderEvents.Function, eventId) or
    /// CommandBuffer.IssuePluginEvent. Parallax renders into the registered CPU buffer (rows top
    /// first); upload it into a texture afterwards. The buffers stay pinned and the scene
    /// referenced until the target is replaced or removed. Remove every target before the editor
    /// reloads the domain (the native library keeps the buffers' addresses across it). Thread-safe.
    /// </summary>
    public static class UnityRenderEvents
    {
        sealed class Target
        {
            public Scene Scene;
            public GCHandle Output, Mask;

            public void Release()
            {
                if (Output.IsAllocated)
                    Output.Free();
                if (Mask.IsAllocated)
                    Mask.Free();
            }
        }

        static readonly Dictionary<int, Target> targets = new Dictionary<int, Target>();

        /// <summary>The render-event function to pass to IssuePluginEvent.</summary>
        public static IntPtr Function { get { return Native.GetRenderEventFunc(); } }

        /// <summary>Event <paramref name="eventId"/> renders <paramref name="scene"/>'s composite into
        /// <paramref name="output"/> (the photo's size, <paramref name="format"/>, rows top first) and, when
        /// not null, the coverage into <paramref name="mask"/> (width * height floats).</summary>
        public static void SetTarget(int eventId, Scene scene, byte[] output, int width, int height,
                                     PlxPixelFormat format = PlxPixelFormat.Rgba8, PlxRenderOptions? options = null,
                                     float[] mask = null)
        {
            int stride = width * Scene.BytesPerPixel(format);
            if (output == null || width <= 0 || height <= 0 || output.Length < stride * height)
                throw new ArgumentException("output cannot hold " + width + "x" + height + " pixels of " + format);
            if (mask != null && mask.Length < width * height)
                throw new ArgumentException("mask holds fewer than width * height floats");
            Target t = new Target();
            t.Scene = scene;
            t.Output = GCHandle.Alloc(output, GCHandleType.Pinned);
            if (mask != null)
                t.Mask = GCHandle.Alloc(mask, GCHandleType.Pinned);
            try
            {
                PlxImageOut o;
                o.Data = t.Output.AddrOfPinnedObject();
                o.Width = (uint)width;
                o.Height = (uint)height;
                o.Stride = (UIntPtr)stride;
                o.Format = (uint)format;
                PlxRenderOptions opts = options.HasValue ? options.Value : PlxRenderOptions.CreateDefault();
                lock (targets)
                {
                    PlxStatus status;
                    if (mask != null)
                    {
                        PlxImageOut m = o;
                        m.Data = t.Mask.AddrOfPinnedObject();
                        m.Stride = (UIntPtr)(width * 4);
                        m.Format = (uint)PlxPixelFormat.GrayF32;
                        status = Native.plx_unity_set_render_target(eventId, scene.Handle, ref opts, ref o, ref m);
                    }
                    else
                    {
                        status = Native.plx_unity_set_render_target(eventId, scene.Handle, ref opts, ref o, IntPtr.Zero);
                    }
                    Errors.Check(status, null);
                    Target old;
                    if (targets.TryGetValue(eventId, out old))
                        old.Release();
                    targets[eventId] = t;
                }
            }
            catch
            {
                t.Release();
                throw;
            }
        }

        /// <summary>Forgets what event <paramref name="eventId"/> renders, and unpins its buffers.</summary>
        public static void RemoveTarget(int eventId)
        {
            lock (targets)
            {
                Errors.Check(Native.plx_unity_set_render_target(eventId, IntPtr.Zero, IntPtr.Zero, IntPtr.Zero, IntPtr.Zero), null);
                Target old;
                if (targets.TryGetValue(eventId, out old))
                {
                    old.Release();
                    targets.Remove(eventId);
                }
            }
        }

        /// <summary>The status of the last run of event <paramref name="eventId"/> (NotAvailable if it
        /// never ran) and how many times it ran.</summary>
        public static PlxStatus LastStatus(int eventId, out ulong runs)
        {
            return Native.plx_unity_last_event_status(eventId, out runs);
        }

        /// <summary>The message of the last run of event <paramref name="eventId"/> ("" after a success).</summary>
        public static string LastMessage(int eventId)
        {
            UIntPtr needed = UIntPtr.Zero;
            return Utf8.Read(
                (buf, len) => Native.plx_unity_last_event_message(eventId, buf, len, out needed),
                () => needed, null);
        }
    }
}
