//! Composition of a program for a key with naga_oil.

use naga_oil::compose::{
    ComposableModuleDescriptor, Composer, ComposerError, NagaModuleDescriptor, ShaderDefValue, ShaderLanguage,
    ShaderType,
};

use super::{CAPABILITIES, FeatureKey, MODULES, Program, ShaderError};

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
    let mut composer = Composer::default().with_capabilities(CAPABILITIES);
    // The composed module is validated once, where it is used: by wgpu when the pipeline is
    // created, and by `validate` in the tests, which cover every variant.
    composer.validate = false;
    for (file, src) in MODULES {
        let src = source_text(file, src)?;
        let added = composer
            .add_composable_module(ComposableModuleDescriptor {
                source: &src,
                file_path: file,
                language: ShaderLanguage::Wgsl,
                shader_defs: defs.clone(),
                ..Default::default()
            })
            .map(|_| ());
        added.map_err(|e| ShaderError::Compose { file: file.to_string(), message: compose_error(&e, &composer) })?;
    }
    let (file, src) = program.source();
    let src = source_text(file, src)?;
    let module = composer.make_naga_module(NagaModuleDescriptor {
        source: &src,
        file_path: file,
        shader_type: ShaderType::Wgsl,
        shader_defs: defs,
        ..Default::default()
    });
    module.map_err(|e| ShaderError::Compose { file: file.to_string(), message: compose_error(&e, &composer) })
}
