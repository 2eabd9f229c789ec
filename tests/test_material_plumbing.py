"""Materials reach every capture (issue 17): the scene edits the captures make on the way
(SfM's texture boost, stereo's textureless mode) keep each object's reflectance model."""


def test_sfm_texture_boost_keeps_the_reflectance_model():
    """The SfM capture's texture boost made every object Lambertian (it rebuilt the
    material from its colour and texture alone): a metal stayed matte in every SfM
    capture, and a material study of SfM measured nothing."""
    from acquire.sfm.capture import _boost_textures
    from scanamp.study.kinds import _scene

    bundle, _ = _scene("object", {"brdf": "conductor", "roughness": 0.15})
    boosted = _boost_textures(bundle.render_scene, 2.0)
    before = {o.name: o.material for o in bundle.render_scene.objects}
    for o in boosted.objects:
        m = before[o.name]
        assert (o.material.brdf, o.material.roughness) == (m.brdf, m.roughness)
        if m.kind == "solid":
            assert o.material.scale == 2.0 * m.scale


def test_textureless_scenes_keep_the_reflectance_model(tmp_path):
    from core.files import write_toml
    from data_synth.scenes import build_scene
    from scanamp.methods import scene_for_capture

    spec = build_scene("object").spec
    spec["objects"][0]["material"] = {**spec["objects"][0].get("material", {}),
                                      "brdf": "conductor", "roughness": 0.2}
    path = tmp_path / "shiny.toml"
    write_toml(path, spec)
    plain = scene_for_capture(str(path), textureless=True)
    m = plain.render_scene.objects[0].material
    assert m.kind == "constant" and (m.brdf, m.roughness) == ("conductor", 0.2)


def test_scene_toml_sets_a_subsurface_anisotropy_and_names_a_bad_one():
    import pytest

    from core.validate import InputError
    from data_synth.scenes import build_scene

    spec = build_scene("object").spec
    spec["objects"][0]["material"] = {"brdf": "subsurface", "mfp": 2e-3, "anisotropy": 0.3}
    m = build_scene(spec).render_scene.objects[0].material
    assert (m.brdf, m.mfp, m.anisotropy) == ("subsurface", 2e-3, 0.3)
    spec["objects"][0]["material"]["anisotropy"] = 1.0
    with pytest.raises(InputError, match="anisotropy"):
        build_scene(spec)
