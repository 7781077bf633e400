//! The process's one naga_oil composer.
//!
//! The shared modules are added to it once, without shader defs; each composition passes the
//! defs of its key, and naga_oil builds a module's variant for the defs that module (and what
//! it imports) tests or substitutes, and keeps it: keys that differ only in defs a module does
//! not read share its variant. The composer is built at first use, from the texts built into
//! the binary or from `STRAHL_SHADER_DIR` ([`source_text`]).

use naga_oil::compose::{
    ComposableModuleDescriptor, Composer, ComposerError, NagaModuleDescriptor, ShaderDefValue, ShaderLanguage,
    ShaderType,
};
use std::collections::HashMap;
use std::sync::{Mutex, OnceLock};

use super::{CAPABILITIES, FeatureKey, MODULES, Program, ShaderError};

/// The composer with every shared module, and the programs' texts read so far, by file.
struct Shaders {
    composer: Composer,
    programs: HashMap<&'static str, String>,
}

/// The process's composer, or why it could not be built (kept: the texts are read once).
static SHADERS: OnceLock<Result<Mutex<Shaders>, ShaderError>> = OnceLock::new();

impl Shaders {
    fn new() -> Result<Self, ShaderError> {
        let mut composer = Composer::default().with_capabilities(CAPABILITIES);
        // A composed module is validated once, where it is used: by wgpu when its shader module
        // is created (once per device and variant, GpuContext), and by `validate` in the tests,
        // which cover every variant.
        composer.validate = false;
        for (file, src) in MODULES {
            let src = source_text(file, src)?;
            let added = composer
                .add_composable_module(ComposableModuleDescriptor {
                    source: &src,
                    file_path: file,
                    language: ShaderLanguage::Wgsl,
                    ..Default::default()
                })
                .map(|_| ());
            added
                .map_err(|e| ShaderError::Compose { file: file.to_string(), message: compose_error(&e, &composer) })?;
        }
        Ok(Shaders { composer, programs: HashMap::new() })
    }
}

/// naga_oil's message for `e`, located in the source it names (file, line, column and the
/// line itself), its decorated names undone.
fn compose_error(e: &ComposerError, composer: &Composer) -> String {
    e.emit_to_string(composer).trim_end().to_string()
}

/// The text of shader `file` (a path like `shaders/modules/types.wgsl`) with the shared
/// values substituted ([`crate::shared`]): the text built into the binary, or, when the
/// environment variable `STRAHL_SHADER_DIR` names a folder laid out like `shaders/`, the file
/// at the same place in it, so that shaders can be edited and measured without rebuilding.
fn source_text(file: &str, built_in: &'static str) -> Result<String, ShaderError> {
    let text = match std::env::var_os("STRAHL_SHADER_DIR") {
        None => built_in.to_string(),
        Some(dir) => {
            let name = file.strip_prefix("shaders/").expect("shader paths start with shaders/");
            let path = std::path::Path::new(&dir).join(name);
            std::fs::read_to_string(&path)
                .map_err(|e| ShaderError::Compose { file: path.display().to_string(), message: e.to_string() })?
        }
    };
    Ok(crate::shared::substitute(&text))
}

/// Composes `program` for `key` into a naga module.
pub fn compose(program: Program, key: FeatureKey) -> Result<naga::Module, ShaderError> {
    let key = key.for_program(program);
    let mut defs = key.shader_defs();
    if program == Program::View {
        defs.insert("COUNT_VISITS".into(), ShaderDefValue::Bool(true));
    }
    compose_source(program.source(), defs)
}

/// Composes the test or diagnostic program `source` (its file and built-in text, an entry of
/// [`super::DIAGNOSTIC`]) for a scene whose key is `key`: with every flag of the key, as the
/// path tracer is composed, so that the same material and geometry code is on.
pub fn compose_diagnostic(source: (&'static str, &'static str), key: FeatureKey) -> Result<naga::Module, ShaderError> {
    compose_source(source, key.shader_defs())
}

/// Composes the top-level shader `file` (whose text is `built_in` unless `STRAHL_SHADER_DIR`
/// says otherwise) with the shader defs `defs`.
fn compose_source(
    (file, built_in): (&'static str, &'static str),
    defs: HashMap<String, ShaderDefValue>,
) -> Result<naga::Module, ShaderError> {
    let lock = SHADERS.get_or_init(|| Shaders::new().map(Mutex::new)).as_ref().map_err(Clone::clone)?;
    let mut shaders = match lock.lock() {
        Ok(shaders) => shaders,
        Err(poisoned) => {
            // naga_oil takes a module out of the composer while it builds a variant of it, so a
            // panic there leaves the composer without it: start again from the texts.
            let mut shaders = poisoned.into_inner();
            *shaders = Shaders::new()?;
            lock.clear_poison();
            shaders
        }
    };
    let Shaders { composer, programs } = &mut *shaders;
    let src = match programs.entry(file) {
        std::collections::hash_map::Entry::Occupied(e) => e.into_mut(),
        std::collections::hash_map::Entry::Vacant(e) => e.insert(source_text(file, built_in)?),
    };
    let module = composer.make_naga_module(NagaModuleDescriptor {
        source: src,
        file_path: file,
        shader_type: ShaderType::Wgsl,
        shader_defs: defs,
        ..Default::default()
    });
    module.map_err(|e| ShaderError::Compose { file: file.to_string(), message: compose_error(&e, composer) })
}
