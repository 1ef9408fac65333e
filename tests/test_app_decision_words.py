"""The engine's decisions worded for an artist (``app/panels/decision_words.py``), on decisions as real runs wrote
them into OUT.json."""

from __future__ import annotations

from app.panels.decision_words import artist_lines

BIKER_BALANCED = {  # gstyle stylize biker.spz --preset balanced (decisions as written, shortened where long)
    "device": "cpu (CPU): auto: torch sees no CUDA device",
    "clip": "CLIP term off (λ_CLIP = 0)",
    "style_scale": "painting matched at 256×160 px: stroke size 1 × the working width; 2,560 feature vectors",
    "colours": "the painting's (full colour match before and after stylization)",
    "levels": "256 px → 512 px, coarse to fine: working-width-sized crops at each finer width, alternating with "
              "whole views at the working width, 6 epochs a level",
    "culled": "1316 of 215468 Gaussians seen by no training camera (24 views): not rendered, not optimised",
    "preprocess": "2 round(s), sizes uneven (flat fraction 0.0384 (even below 0.001))",
    "precision": "bf16 (auto): remembered for AMD EPYC | torch 2.13.0+cpu",
    "broad_strokes": "lambda 200 (multiscale): NNFM on the render and the painting both shrunk 2x, 4x and 8x",
}


def test_a_balanced_run_reads_as_plain_lines():
    assert artist_lines(BIKER_BALANCED) == [
        "Computing on the CPU",
        "Paints at 256 px wide first, then sharpens at 512 px",
        "Brush strokes as the painting shows them at 256×160 px (stroke size 1)",
        "Colours: the painting's",
        "Large shapes: the painting's strokes matched at half, quarter and eighth size (no CLIP weights)",
        "Large flat splats split first (2 rounds) so strokes can cross them",
        "1316 splats no camera sees are left as they are",
        "Networks in bf16 (faster on this machine, the same result)",
    ]


def test_a_gpu_run_names_the_card_and_missing_decisions_give_no_line():
    lines = artist_lines({"device": "cuda (NVIDIA H200 (140 GiB, CUDA 13.0)): auto: torch sees a CUDA device",
                          "culled": "0 of 500 Gaussians seen by no training camera", "levels": "256 px"})
    assert lines == ["Computing on the GPU (NVIDIA H200)"]
    assert artist_lines({}) == []


def test_the_clip_stand_in_and_one_unseen_splat_read_right():
    lines = artist_lines({"clip": "CLIP ViT-B/32 weights not found (looked in ~/.cache/clip); using the coarse-VGG "
                                  "substitute (no CLIP weights)",
                          "culled": "1 of 171 Gaussians seen by no training camera (3 views)"})
    assert lines == ["Large shapes: a coarse stand-in for CLIP (no CLIP weights found)",
                     "1 splat no camera sees is left as it is"]
    assert artist_lines({"clip": "CLIP weights from /x/ViT-B-32.pt"}) == ["Large shapes: CLIP"]
    assert artist_lines({"clip": "CLIP term off (λ_CLIP = 0)"}) == []


def test_a_run_capped_at_its_photos_width_says_where_it_ends():
    lines = artist_lines({"levels": "256 px → 504 px, coarse to fine: crops",
                          "levels_capped": "levels 512 px, 1024 px asked for; the photos are 504 px wide, so the run "
                                           "ends at 504 px (a wider level would fit enlarged photos)"})
    assert lines == ["Paints at 256 px wide first, then sharpens at 504 px",
                     "Ends at the photos' width, 504 px: a wider level would only enlarge them"]


def test_the_level_of_detail_says_what_the_cut_holds():
    note = ("1,200,000 Gaussians as 140,211 parents at 256 px (1,105,000 merged into 45,211 in cells of 1 px; "
            "every input Gaussian is written with its own geometry)")
    assert artist_lines({"lod": note}) == [
        "Paints 1,200,000 splats as 140,211 groups at 256 px; every splat is exported with its own shape"]
    assert artist_lines({"lod": "off (--lod off): every Gaussian is stylized on its own"}) == []
