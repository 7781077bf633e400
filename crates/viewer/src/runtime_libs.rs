//! The shared libraries the viewer's window system loads at run time. winit opens Xlib and its
//! extensions with `dlopen` only when the window is created, so a machine without them (a
//! minimal container, a server install) fails deep inside the event loop with "Failed to load
//! one of xlib's shared libraries", naming neither the library nor its package. Each is tried
//! here first, and the error names every missing one with the Debian package that ships it.

/// (soname, Debian/Ubuntu package) of each library the X11 window and its Vulkan surface load:
/// what winit 0.30 opens through x11-dl, x11rb and xkbcommon-dl, and the Vulkan loader.
pub const X11_LIBRARIES: [(&str, &str); 8] = [
    ("libX11.so.6", "libx11-6"),
    ("libX11-xcb.so.1", "libx11-xcb1"),
    ("libxcb.so.1", "libxcb1"),
    ("libXcursor.so.1", "libxcursor1"),
    ("libXi.so.6", "libxi6"),
    ("libxkbcommon.so.0", "libxkbcommon0"),
    ("libxkbcommon-x11.so.0", "libxkbcommon-x11-0"),
    ("libvulkan.so.1", "libvulkan1"),
];

/// Whether the dynamic loader finds `soname` (loaded and unloaded again).
#[cfg(target_os = "linux")]
fn loads(soname: &str) -> bool {
    let Ok(name) = std::ffi::CString::new(soname) else { return false };
    // SAFETY: `name` is a NUL-terminated string; a library that loads is closed again at once
    // (its initialisers run, as they would when winit loads it).
    unsafe {
        let handle = libc::dlopen(name.as_ptr(), libc::RTLD_LAZY | libc::RTLD_LOCAL);
        if handle.is_null() {
            return false;
        }
        libc::dlclose(handle);
    }
    true
}

#[cfg(not(target_os = "linux"))]
fn loads(_soname: &str) -> bool {
    true
}

/// The libraries of `wanted` that do not load, as (soname, package).
pub fn missing<'a>(wanted: &[(&'a str, &'a str)]) -> Vec<(&'a str, &'a str)> {
    wanted.iter().copied().filter(|(soname, _)| !loads(soname)).collect()
}

/// The error for `missing` libraries, naming each and how to install them all.
pub fn missing_message(missing: &[(&str, &str)]) -> String {
    let names: Vec<String> = missing.iter().map(|(soname, package)| format!("{soname} (package {package})")).collect();
    let packages: Vec<&str> = missing.iter().map(|&(_, package)| package).collect();
    format!(
        "strahl view cannot open a window: the window system's libraries {} are not installed; on \
         Debian or Ubuntu: apt-get install {}",
        names.join(", "),
        packages.join(" ")
    )
}

/// Fails with [`missing_message`] where one of [`X11_LIBRARIES`] is missing.
pub fn check() -> Result<(), String> {
    let missing = missing(&X11_LIBRARIES);
    if missing.is_empty() { Ok(()) } else { Err(missing_message(&missing)) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_library_is_named_with_its_package() {
        let wanted = [("libc.so.6", "libc6"), ("libstrahl-absent.so.7", "strahl-absent7")];
        let gone = missing(&wanted);
        if cfg!(target_os = "linux") {
            assert_eq!(gone, [("libstrahl-absent.so.7", "strahl-absent7")]);
        }
        let m = missing_message(&[("libXcursor.so.1", "libxcursor1"), ("libXi.so.6", "libxi6")]);
        assert!(m.contains("libXcursor.so.1 (package libxcursor1), libXi.so.6 (package libxi6)"), "{m}");
        assert!(m.ends_with("apt-get install libxcursor1 libxi6"), "{m}");
    }
}
