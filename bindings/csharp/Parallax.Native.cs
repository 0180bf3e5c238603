// Parallax C# bindings: the P/Invoke declarations of the whole C API (include/parallax.h).
//
// Hand-written and kept in step with the header by tests/csharp.rs, which fails when an exported
// plx_ function has no DllImport here, when a parameter count or type differs, or when a struct's
// or enum's fields differ in count, order, name or type. Names follow one rule: functions keep
// their C names; types and fields are the C names in PascalCase (plx_light -> PlxLight,
// max_image_pixels -> MaxImagePixels); enum values drop the enum's prefix
// (PLX_STATUS_NULL_ARGUMENT -> PlxStatus.NullArgument).
//
// C#-7 level, no unsafe code, no dependency besides mscorlib: compiles with Mono's mcs and in
// Unity. bindings/unity/Runtime/ holds an identical copy (checked by the same test).
//
// Type mapping: size_t -> UIntPtr; const char* inputs -> NUL-terminated UTF-8 byte[] (see
// Utf8.Encode); char* output buffers -> byte[]; returned const char* -> IntPtr (Utf8.Decode);
// nullable struct pointers -> an overload taking IntPtr (pass IntPtr.Zero for NULL); nullable
// float* -> float[] (null = NULL); plx_scene*/plx_context* -> SceneHandle/ContextHandle.
using System;
using System.Runtime.InteropServices;

namespace Parallax
{
    /// <summary>Result of every fallible C function (plx_status); Ok is zero.</summary>
    public enum PlxStatus : int
    {
        Ok = 0,
        NullArgument = 1,
        InvalidArgument = 2,
        SizeMismatch = 3,
        TooLarge = 4,
        Format = 5,
        Io = 6,
        Unsupported = 7,
        Gpu = 8,
        NotAvailable = 9,
        Panic = 10,
        Internal = 11,
        Cancelled = 12,
    }

    /// <summary>Pixel formats of PlxImage.Format / PlxImageOut.Format.</summary>
    public enum PlxPixelFormat : uint
    {
        Gray8 = 0,
        Rgb8 = 1,
        Rgba8 = 2,
        Bgra8 = 3,
        GrayF32 = 4,
        RgbF32 = 5,
        RgbaF16 = 6,
        RgbaF32 = 7,
    }

    /// <summary>Presets of PlxStereoOptions.Preset.</summary>
    public enum PlxStereoPreset : uint
    {
        Fast = 0,
        Balanced = 1,
        Quality = 2,
    }

    /// <summary>Matching methods of PlxStereoOptions.Method.</summary>
    public enum PlxStereoMethod : uint
    {
        PresetDefault = 0,
        CensusSgm8 = 1,
        CensusSgm4 = 2,
        SadDp = 3,
    }

    /// <summary>Encodings of plx_scene_depth_buffer.</summary>
    public enum PlxDepthEncoding : uint
    {
        LinearMeters = 0,
        OpenglWindow = 1,
        WebgpuZeroToOne = 2,
        ReversedZ = 3,
    }

    /// <summary>Orientation of a surface relative to the estimated up (PlxSurface.Kind).</summary>
    public enum PlxSurfaceKind : uint
    {
        Horizontal = 0,
        Overhead = 1,
        Vertical = 2,
        Slanted = 3,
    }

    /// <summary>Kinds of PlxLight.Kind.</summary>
    public enum PlxLightKind : uint
    {
        Directional = 0,
        Point = 1,
        Area = 2,
    }

    /// <summary>PlxRenderOptions.Shading values.</summary>
    public enum PlxShadingMode : uint
    {
        Pbr = 0,
        Thesis = 1,
    }

    /// <summary>PlxRenderOptions.Shadows values.</summary>
    public enum PlxShadowMode : uint
    {
        ThesisEsm = 0,
        Evsm = 1,
        Pcss = 2,
        Off = 3,
    }

    /// <summary>Levels of the log callback, most severe first.</summary>
    public enum PlxLogLevel : uint
    {
        Error = 0,
        Warn = 1,
        Info = 2,
        Debug = 3,
    }

    /// <summary>Options of plx_context_new; start from PlxContextOptions.CreateDefault().</summary>
    [StructLayout(LayoutKind.Sequential)]
    public struct PlxContextOptions
    {
        public UIntPtr Size;
        public ulong MaxImagePixels;
        /// <summary>NULL or a NUL-terminated UTF-8 substring of the GPU adapter name.</summary>
        public IntPtr AdapterName;

        /// <summary>The defaults (plx_context_options_init), Size set to this struct's size.</summary>
        public static PlxContextOptions CreateDefault()
        {
            PlxContextOptions o;
            Errors.Check(Native.plx_context_options_init(out o), null);
            o.Size = (UIntPtr)Marshal.SizeOf(typeof(PlxContextOptions));
            return o;
        }
    }

    /// <summary>An image in caller memory that Parallax fills (rows top first).</summary>
    [StructLayout(LayoutKind.Sequential)]
    public struct PlxImageOut
    {
        public IntPtr Data;
        public uint Width;
        public uint Height;
        public UIntPtr Stride;
        /// <summary>A PlxPixelFormat value.</summary>
        public uint Format;
    }

    /// <summary>One light, in the left camera's frame (+X right, +Y up, looking along -Z; metres).</summary>
    [StructLayout(LayoutKind.Sequential)]
    public struct PlxLight
    {
        /// <summary>A PlxLightKind value.</summary>
        public uint Kind;
        [MarshalAs(UnmanagedType.ByValArray, SizeConst = 3)]
        public float[] Position;
        /// <summary>Unit direction the light travels (from the light to the scene).</summary>
        [MarshalAs(UnmanagedType.ByValArray, SizeConst = 3)]
        public float[] Direction;
        /// <summary>Diameter in metres (point, area) or angular diameter in degrees (directional).</summary>
        public float Size;
        [MarshalAs(UnmanagedType.ByValArray, SizeConst = 3)]
        public float[] Intensity;
        public float Confidence;

        /// <summary>A directional light travelling along <paramref name="direction"/>.</summary>
        public static PlxLight Directional(float[] direction, float angularSizeDeg, float[] rgb)
        {
            PlxLight l = new PlxLight();
            l.Kind = (uint)PlxLightKind.Directional;
            l.Position = new float[3];
            l.Direction = (float[])direction.Clone();
            l.Size = angularSizeDeg;
            l.Intensity = (float[])rgb.Clone();
            l.Confidence = 1;
            return l;
        }
    }

    /// <summary>An image in caller memory, copied by Parallax (rows top first).</summary>
    [StructLayout(LayoutKind.Sequential)]
    public struct PlxImage
    {
        public IntPtr Data;
        public uint Width;
        public uint Height;
        public UIntPtr Stride;
        /// <summary>A PlxPixelFormat value.</summary>
        public uint Format;
    }

    /// <summary>Pinhole intrinsics of the left camera, pixels.</summary>
    [StructLayout(LayoutKind.Sequential)]
    public struct PlxCamera
    {
        public float Fx;
        public float Fy;
        public float Cx;
        public float Cy;
    }

    /// <summary>A borrowed grid of floats in library memory (valid until the scene changes).</summary>
    [StructLayout(LayoutKind.Sequential)]
    public struct PlxFloatView
    {
        public IntPtr Data;
        public uint Width;
        public uint Height;
        public UIntPtr Stride;
    }

    /// <summary>How depth becomes the scene mesh; start from PlxMeshOptions.CreateDefault().</summary>
    [StructLayout(LayoutKind.Sequential)]
    public struct PlxMeshOptions
    {
        public UIntPtr Size;
        public uint Step;
        public float MaxGrazingAngleDeg;
        public float DepthNoise;
        public uint MaxTriangles;
        /// <summary>Nonzero (default): vertices on a detected support surface take its normal.</summary>
        public uint SnapToSurfaces;

        /// <summary>The defaults (plx_mesh_options_init), Size set to this struct's size.</summary>
        public static PlxMeshOptions CreateDefault()
        {
            PlxMeshOptions o;
            Errors.Check(Native.plx_mesh_options_init(out o), null);
            o.Size = (UIntPtr)Marshal.SizeOf(typeof(PlxMeshOptions));
            return o;
        }
    }

    /// <summary>A borrowed triangle mesh in library memory (valid until the scene changes).</summary>
    [StructLayout(LayoutKind.Sequential)]
    public struct PlxMeshView
    {
        public IntPtr Positions;
        public IntPtr Normals;
        public IntPtr Tangents;
        public IntPtr Uvs;
        public UIntPtr VertexCount;
        public IntPtr Indices;
        public UIntPtr IndexCount;
    }

    /// <summary>A planar surface of the scene, camera frame, metres.</summary>
    [StructLayout(LayoutKind.Sequential)]
    public struct PlxSurface
    {
        [MarshalAs(UnmanagedType.ByValArray, SizeConst = 3)]
        public float[] Normal;
        [MarshalAs(UnmanagedType.ByValArray, SizeConst = 3)]
        public float[] Centroid;
        public float Offset;
        public ulong Inliers;
        public float RmsM;
        public float AreaM2;
        /// <summary>A PlxSurfaceKind value.</summary>
        public uint Kind;
    }

    /// <summary>What plx_scene_pick found.</summary>
    [StructLayout(LayoutKind.Sequential)]
    public struct PlxHit
    {
        /// <summary>1 when the pixel's ray hit the scene mesh.</summary>
        public uint Hit;
        [MarshalAs(UnmanagedType.ByValArray, SizeConst = 3)]
        public float[] Point;
        [MarshalAs(UnmanagedType.ByValArray, SizeConst = 3)]
        public float[] Normal;
        public float Distance;
        public uint Triangle;
    }

    /// <summary>How the composite is rendered; start from PlxRenderOptions.CreateDefault().</summary>
    [StructLayout(LayoutKind.Sequential)]
    public struct PlxRenderOptions
    {
        public UIntPtr Size;
        /// <summary>A PlxShadingMode value.</summary>
        public uint Shading;
        /// <summary>A PlxShadowMode value.</summary>
        public uint Shadows;
        public uint ShadowMapSize;
        public uint FilterRadius;
        public uint Msaa;

        /// <summary>The defaults (plx_render_options_init), Size set to this struct's size.</summary>
        public static PlxRenderOptions CreateDefault()
        {
            PlxRenderOptions o;
            Errors.Check(Native.plx_render_options_init(out o), null);
            o.Size = (UIntPtr)Marshal.SizeOf(typeof(PlxRenderOptions));
            return o;
        }
    }

    /// <summary>Calibration of a rectified pair.</summary>
    [StructLayout(LayoutKind.Sequential)]
    public struct PlxCalibration
    {
        public double FocalPx;
        public double Cx;
        public double Cy;
        public double BaselineM;
        public double Doffs;
        public uint MaxDisparity;
    }

    /// <summary>Options of the stereo matcher; start from PlxStereoOptions.CreateDefault().</summary>
    [StructLayout(LayoutKind.Sequential)]
    public struct PlxStereoOptions
    {
        public UIntPtr Size;
        /// <summary>A PlxStereoPreset value.</summary>
        public uint Preset;
        public uint MaxDisparity;
        /// <summary>A PlxStereoMethod value.</summary>
        public uint Method;
        public uint Fill;
        public int CoarseLevels;

        /// <summary>The defaults (plx_stereo_options_init), Size set to this struct's size.</summary>
        public static PlxStereoOptions CreateDefault()
        {
            PlxStereoOptions o;
            Errors.Check(Native.plx_stereo_options_init(out o), null);
            o.Size = (UIntPtr)Marshal.SizeOf(typeof(PlxStereoOptions));
            return o;
        }
    }

    /// <summary>A Unity interface GUID (UnityInterfaceGUID).</summary>
    [StructLayout(LayoutKind.Sequential)]
    public struct PlxUnityGuid
    {
        public ulong High;
        public ulong Low;
    }

    /// <summary>The layout of Unity's IUnityInterfaces (function pointers).</summary>
    [StructLayout(LayoutKind.Sequential)]
    public struct PlxUnityInterfaces
    {
        public IntPtr GetInterface;
        public IntPtr RegisterInterface;
        public IntPtr GetInterfaceSplit;
        public IntPtr RegisterInterfaceSplit;
    }

    /// <summary>plx_unity_rendering_event: Unity's UnityRenderingEvent, run on its render thread.</summary>
    [UnmanagedFunctionPointer(CallingConvention.Cdecl)]
    public delegate void PlxUnityRenderingEvent(int eventId);

    /// <summary>plx_log_fn: one log line; message is NUL-terminated UTF-8, valid during the call.</summary>
    [UnmanagedFunctionPointer(CallingConvention.Cdecl)]
    public delegate void PlxLogFn(IntPtr userData, uint level, IntPtr message);

    /// <summary>plx_progress_fn: return 0 to go on, nonzero to cancel.</summary>
    [UnmanagedFunctionPointer(CallingConvention.Cdecl)]
    public delegate int PlxProgressFn(IntPtr userData, IntPtr stage, float fraction);

    /// <summary>Owns a plx_context; freed with plx_context_free. Thread-safe.</summary>
    public sealed class ContextHandle : SafeHandle
    {
        public ContextHandle() : base(IntPtr.Zero, true) { }

        public override bool IsInvalid { get { return handle == IntPtr.Zero; } }

        protected override bool ReleaseHandle()
        {
            Native.plx_context_free(handle);
            return true;
        }
    }

    /// <summary>Owns a plx_scene; freed with plx_scene_free. One thread at a time.</summary>
    public sealed class SceneHandle : SafeHandle
    {
        // The progress callback's user data, freed after the scene (which may call it until then).
        internal GCHandle Progress;

        public SceneHandle() : base(IntPtr.Zero, true) { }

        public override bool IsInvalid { get { return handle == IntPtr.Zero; } }

        protected override bool ReleaseHandle()
        {
            Native.plx_scene_free(handle);
            if (Progress.IsAllocated)
                Progress.Free();
            return true;
        }
    }

#if !UNITY_5_3_OR_NEWER
    /// <summary>
    /// Marks a static method that native code calls back. In Unity the wrapper uses
    /// AOT.MonoPInvokeCallbackAttribute (IL2CPP needs it); elsewhere this stand-in.
    /// </summary>
    [AttributeUsage(AttributeTargets.Method)]
    public sealed class MonoPInvokeCallbackAttribute : Attribute
    {
        public MonoPInvokeCallbackAttribute(Type type) { }
    }
#endif

    /// <summary>The C functions, one DllImport each (C names and parameter order).</summary>
    public static class Native
    {
        /// <summary>The native library: libparallax.so / parallax.dll / libparallax.dylib;
        /// linked statically into the player on iOS.</summary>
        public const string Library =
#if UNITY_IOS && !UNITY_EDITOR
            "__Internal";
#else
            "parallax";
#endif

        // ---- artefacts ----

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_add_artefact_path(SceneHandle scene, byte[] path, float[] transform, out uint outId);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_add_artefact_memory(SceneHandle scene, byte[] bytes, UIntPtr len, float[] transform, out uint outId);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_set_artefact_transform(SceneHandle scene, uint id, float[] transform);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_set_artefact_flags(SceneHandle scene, uint id, uint visible, uint castsShadow, uint receivesShadow);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_remove_artefact(SceneHandle scene, uint id);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_artefact_bounds(SceneHandle scene, uint id, [Out] float[] localMin, [Out] float[] localMax, [Out] float[] worldMin, [Out] float[] worldMax);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_place_artefact(SceneHandle scene, uint id, float x, float y, float sizeM, float yawDeg, [Out] float[] outTransform);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_artefact_warnings(SceneHandle scene, uint id, [Out] byte[] buf, UIntPtr len, out UIntPtr needed, out UIntPtr count);

        // ---- context ----

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_context_options_init(out PlxContextOptions options);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_context_new(ref PlxContextOptions options, out ContextHandle context);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_context_new(IntPtr options, out ContextHandle context);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern void plx_context_free(IntPtr context);

        // ---- image I/O ----

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_photo(SceneHandle scene, ref PlxImageOut output);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_photo_size(SceneHandle scene, out uint width, out uint height);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_load_stereo_pair(SceneHandle scene, byte[] leftPath, byte[] rightPath);

        // ---- lights ----

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_set_lights(SceneHandle scene, [In] PlxLight[] lights, UIntPtr count);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_reset_lights(SceneHandle scene);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_set_sh9(SceneHandle scene, float[] sh9);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_set_insertion_point(SceneHandle scene, float[] point);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_set_environment_equirect(SceneHandle scene, ref PlxImage image);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_set_environment_equirect(SceneHandle scene, IntPtr image);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_lights(SceneHandle scene, [In, Out] PlxLight[] output, UIntPtr capacity, out UIntPtr count);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_main_light(SceneHandle scene, [Out] float[] direction, [Out] float[] rgb);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_sh9(SceneHandle scene, [Out] float[] output);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_environment_cube_size(SceneHandle scene, out uint size);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_environment_cube_face(SceneHandle scene, uint face, ref PlxImageOut output);

        // ---- logging ----

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_set_log_callback(PlxLogFn callback, IntPtr userData, uint maxLevel);

        // ---- host depth, camera, mesh ----

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_set_depth(SceneHandle scene, float[] depth, uint width, uint height, UIntPtr strideBytes, float[] confidence, UIntPtr confidenceStrideBytes, ref PlxCamera camera);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_set_depth(SceneHandle scene, float[] depth, uint width, uint height, UIntPtr strideBytes, float[] confidence, UIntPtr confidenceStrideBytes, IntPtr camera);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_clear_depth(SceneHandle scene);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_set_clip(SceneHandle scene, float near, float far);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_camera(SceneHandle scene, out PlxCamera output, out float near, out float far);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_depth_buffer(SceneHandle scene, uint encoding, float near, float far, out PlxFloatView output);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_mesh_options_init(out PlxMeshOptions options);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_set_mesh_options(SceneHandle scene, ref PlxMeshOptions options);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_set_mesh_options(SceneHandle scene, IntPtr options);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_mesh(SceneHandle scene, out PlxMeshView output);

        // ---- progress ----

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_set_progress_callback(SceneHandle scene, PlxProgressFn callback, IntPtr userData);

        // ---- surfaces, picking, placement ----

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_surfaces(SceneHandle scene, out UIntPtr count, out IntPtr output);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_up(SceneHandle scene, [Out] float[] output);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_set_up(SceneHandle scene, float[] up);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_pick(SceneHandle scene, float x, float y, out PlxHit output);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_place(SceneHandle scene, float x, float y, float sizeM, float yawDeg, [Out] float[] outMatrix);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_place_on_ray(SceneHandle scene, float[] origin, float[] direction, float sizeM, float yawDeg, [Out] float[] outMatrix);

        // ---- render ----

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_render_options_init(out PlxRenderOptions options);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_render(SceneHandle scene, ref PlxRenderOptions options, ref PlxImageOut output, ref PlxImageOut maskOut);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_render(SceneHandle scene, ref PlxRenderOptions options, ref PlxImageOut output, IntPtr maskOut);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_render(SceneHandle scene, IntPtr options, ref PlxImageOut output, IntPtr maskOut);

        // ---- scene ----

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_new(ContextHandle context, out SceneHandle scene);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_clone(SceneHandle scene, out SceneHandle copy);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern void plx_scene_free(IntPtr scene);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_set_stereo_pair(SceneHandle scene, ref PlxImage left, ref PlxImage right);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_set_photo(SceneHandle scene, ref PlxImage photo);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_set_calibration(SceneHandle scene, ref PlxCalibration calibration);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_report(SceneHandle scene, [Out] byte[] buf, UIntPtr len, out UIntPtr needed);

        // ---- status, version, errors ----

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern IntPtr plx_status_str(uint status);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern IntPtr plx_version();

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_last_error_message(IntPtr handle, [Out] byte[] buf, UIntPtr len, out UIntPtr needed);

        // ---- Unity rendering plugin (a library built with the `unity` feature) ----

        /// <summary>The render-event function for GL.IssuePluginEvent / CommandBuffer.IssuePluginEvent.</summary>
        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern IntPtr GetRenderEventFunc();

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_unity_set_render_target(int eventId, SceneHandle scene, ref PlxRenderOptions options, ref PlxImageOut output, ref PlxImageOut maskOut);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_unity_set_render_target(int eventId, SceneHandle scene, ref PlxRenderOptions options, ref PlxImageOut output, IntPtr maskOut);

        /// <summary>With scene IntPtr.Zero: removes the target of eventId.</summary>
        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_unity_set_render_target(int eventId, IntPtr scene, IntPtr options, IntPtr output, IntPtr maskOut);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_unity_last_event_status(int eventId, out ulong runs);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_unity_last_event_message(int eventId, [Out] byte[] buf, UIntPtr len, out UIntPtr needed);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern IntPtr plx_unity_interfaces_get();

        // ---- stereo ----

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_stereo_options_init(out PlxStereoOptions options);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_set_stereo_options(SceneHandle scene, ref PlxStereoOptions options);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_set_stereo_options(SceneHandle scene, IntPtr options);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_disparity(SceneHandle scene, out PlxFloatView output);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_confidence(SceneHandle scene, out PlxFloatView output);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl)]
        public static extern PlxStatus plx_scene_depth(SceneHandle scene, out PlxFloatView output);
    }
}
