// Named segments: TotalSegmentator's class maps, the label table of its NIfTI header extension,
// and the resolution of a selection ("lung_upper_lobe_left", "3") into label values.
#include <algorithm>
#include <array>
#include <charconv>
#include <fmt/format.h>
#include <map>
#include <optional>
#include <set>
#include <string_view>

#include "pneuma/core/error.h"
#include "pneuma/image/label_map.h"

namespace pneuma::image {
namespace {

// TotalSegmentator's task "total", label value = index + 1: `class_map["total"]` (v2, 117
// classes) and `class_map["total_v1"]` (104) of totalsegmentator/map_to_binary.py
// (wasserth/TotalSegmentator, commit 0275d30).
constexpr std::array<std::string_view, 117> kTotalV2 = {"spleen",
                                                        "kidney_right",
                                                        "kidney_left",
                                                        "gallbladder",
                                                        "liver",
                                                        "stomach",
                                                        "pancreas",
                                                        "adrenal_gland_right",
                                                        "adrenal_gland_left",
                                                        "lung_upper_lobe_left",
                                                        "lung_lower_lobe_left",
                                                        "lung_upper_lobe_right",
                                                        "lung_middle_lobe_right",
                                                        "lung_lower_lobe_right",
                                                        "esophagus",
                                                        "trachea",
                                                        "thyroid_gland",
                                                        "small_bowel",
                                                        "duodenum",
                                                        "colon",
                                                        "urinary_bladder",
                                                        "prostate",
                                                        "kidney_cyst_left",
                                                        "kidney_cyst_right",
                                                        "sacrum",
                                                        "vertebrae_S1",
                                                        "vertebrae_L5",
                                                        "vertebrae_L4",
                                                        "vertebrae_L3",
                                                        "vertebrae_L2",
                                                        "vertebrae_L1",
                                                        "vertebrae_T12",
                                                        "vertebrae_T11",
                                                        "vertebrae_T10",
                                                        "vertebrae_T9",
                                                        "vertebrae_T8",
                                                        "vertebrae_T7",
                                                        "vertebrae_T6",
                                                        "vertebrae_T5",
                                                        "vertebrae_T4",
                                                        "vertebrae_T3",
                                                        "vertebrae_T2",
                                                        "vertebrae_T1",
                                                        "vertebrae_C7",
                                                        "vertebrae_C6",
                                                        "vertebrae_C5",
                                                        "vertebrae_C4",
                                                        "vertebrae_C3",
                                                        "vertebrae_C2",
                                                        "vertebrae_C1",
                                                        "heart",
                                                        "aorta",
                                                        "pulmonary_vein",
                                                        "brachiocephalic_trunk",
                                                        "subclavian_artery_right",
                                                        "subclavian_artery_left",
                                                        "common_carotid_artery_right",
                                                        "common_carotid_artery_left",
                                                        "brachiocephalic_vein_left",
                                                        "brachiocephalic_vein_right",
                                                        "atrial_appendage_left",
                                                        "superior_vena_cava",
                                                        "inferior_vena_cava",
                                                        "portal_vein_and_splenic_vein",
                                                        "iliac_artery_left",
                                                        "iliac_artery_right",
                                                        "iliac_vena_left",
                                                        "iliac_vena_right",
                                                        "humerus_left",
                                                        "humerus_right",
                                                        "scapula_left",
                                                        "scapula_right",
                                                        "clavicula_left",
                                                        "clavicula_right",
                                                        "femur_left",
                                                        "femur_right",
                                                        "hip_left",
                                                        "hip_right",
                                                        "spinal_cord",
                                                        "gluteus_maximus_left",
                                                        "gluteus_maximus_right",
                                                        "gluteus_medius_left",
                                                        "gluteus_medius_right",
                                                        "gluteus_minimus_left",
                                                        "gluteus_minimus_right",
                                                        "autochthon_left",
                                                        "autochthon_right",
                                                        "iliopsoas_left",
                                                        "iliopsoas_right",
                                                        "brain",
                                                        "skull",
                                                        "rib_left_1",
                                                        "rib_left_2",
                                                        "rib_left_3",
                                                        "rib_left_4",
                                                        "rib_left_5",
                                                        "rib_left_6",
                                                        "rib_left_7",
                                                        "rib_left_8",
                                                        "rib_left_9",
                                                        "rib_left_10",
                                                        "rib_left_11",
                                                        "rib_left_12",
                                                        "rib_right_1",
                                                        "rib_right_2",
                                                        "rib_right_3",
                                                        "rib_right_4",
                                                        "rib_right_5",
                                                        "rib_right_6",
                                                        "rib_right_7",
                                                        "rib_right_8",
                                                        "rib_right_9",
                                                        "rib_right_10",
                                                        "rib_right_11",
                                                        "rib_right_12",
                                                        "sternum",
                                                        "costal_cartilages"};

constexpr std::array<std::string_view, 104> kTotalV1 = {"spleen",
                                                        "kidney_right",
                                                        "kidney_left",
                                                        "gallbladder",
                                                        "liver",
                                                        "stomach",
                                                        "aorta",
                                                        "inferior_vena_cava",
                                                        "portal_vein_and_splenic_vein",
                                                        "pancreas",
                                                        "adrenal_gland_right",
                                                        "adrenal_gland_left",
                                                        "lung_upper_lobe_left",
                                                        "lung_lower_lobe_left",
                                                        "lung_upper_lobe_right",
                                                        "lung_middle_lobe_right",
                                                        "lung_lower_lobe_right",
                                                        "vertebrae_L5",
                                                        "vertebrae_L4",
                                                        "vertebrae_L3",
                                                        "vertebrae_L2",
                                                        "vertebrae_L1",
                                                        "vertebrae_T12",
                                                        "vertebrae_T11",
                                                        "vertebrae_T10",
                                                        "vertebrae_T9",
                                                        "vertebrae_T8",
                                                        "vertebrae_T7",
                                                        "vertebrae_T6",
                                                        "vertebrae_T5",
                                                        "vertebrae_T4",
                                                        "vertebrae_T3",
                                                        "vertebrae_T2",
                                                        "vertebrae_T1",
                                                        "vertebrae_C7",
                                                        "vertebrae_C6",
                                                        "vertebrae_C5",
                                                        "vertebrae_C4",
                                                        "vertebrae_C3",
                                                        "vertebrae_C2",
                                                        "vertebrae_C1",
                                                        "esophagus",
                                                        "trachea",
                                                        "heart_myocardium",
                                                        "heart_atrium_left",
                                                        "heart_ventricle_left",
                                                        "heart_atrium_right",
                                                        "heart_ventricle_right",
                                                        "pulmonary_artery",
                                                        "brain",
                                                        "iliac_artery_left",
                                                        "iliac_artery_right",
                                                        "iliac_vena_left",
                                                        "iliac_vena_right",
                                                        "small_bowel",
                                                        "duodenum",
                                                        "colon",
                                                        "rib_left_1",
                                                        "rib_left_2",
                                                        "rib_left_3",
                                                        "rib_left_4",
                                                        "rib_left_5",
                                                        "rib_left_6",
                                                        "rib_left_7",
                                                        "rib_left_8",
                                                        "rib_left_9",
                                                        "rib_left_10",
                                                        "rib_left_11",
                                                        "rib_left_12",
                                                        "rib_right_1",
                                                        "rib_right_2",
                                                        "rib_right_3",
                                                        "rib_right_4",
                                                        "rib_right_5",
                                                        "rib_right_6",
                                                        "rib_right_7",
                                                        "rib_right_8",
                                                        "rib_right_9",
                                                        "rib_right_10",
                                                        "rib_right_11",
                                                        "rib_right_12",
                                                        "humerus_left",
                                                        "humerus_right",
                                                        "scapula_left",
                                                        "scapula_right",
                                                        "clavicula_left",
                                                        "clavicula_right",
                                                        "femur_left",
                                                        "femur_right",
                                                        "hip_left",
                                                        "hip_right",
                                                        "sacrum",
                                                        "face",
                                                        "gluteus_maximus_left",
                                                        "gluteus_maximus_right",
                                                        "gluteus_medius_left",
                                                        "gluteus_medius_right",
                                                        "gluteus_minimus_left",
                                                        "gluteus_minimus_right",
                                                        "autochthon_left",
                                                        "autochthon_right",
                                                        "iliopsoas_left",
                                                        "iliopsoas_right",
                                                        "urinary_bladder"};

template <std::size_t N>
std::vector<Segment> table(const std::array<std::string_view, N>& names) {
  std::vector<Segment> out;
  out.reserve(N);
  for (std::size_t i = 0; i < N; ++i) out.push_back({std::string(names[i]), static_cast<std::int32_t>(i + 1)});
  return out;
}

std::optional<int> parse_int(std::string_view text) {
  int value = 0;
  const char* end = text.data() + text.size();
  if (!text.empty() && text.front() == '+') text.remove_prefix(1);
  const auto [at, ec] = std::from_chars(text.data(), end, value);
  if (text.empty() || ec != std::errc() || at != end) return std::nullopt;
  return value;
}

std::string list_segments(const std::vector<Segment>& segments) {
  std::string out;
  for (const Segment& s : segments) {
    if (!out.empty()) out += ", ";
    out += s.name + " = " + std::to_string(s.label);
  }
  return out;
}

std::string list_present(const std::set<int>& present) {
  std::string out;
  std::size_t shown = 0;
  for (int value : present) {
    if (shown++ == 20) return out + ", ...";
    if (!out.empty()) out += ", ";
    out += std::to_string(value);
  }
  return out;
}

}  // namespace

std::vector<Segment> totalsegmentator_classes(int version) {
  if (version == 1) return table(kTotalV1);
  if (version == 2) return table(kTotalV2);
  throw ValueError("TotalSegmentator version " + std::to_string(version) + ": expected 1 or 2");
}

std::vector<std::string> totalsegmentator_lung_lobes() {
  return {"lung_upper_lobe_left", "lung_lower_lobe_left", "lung_upper_lobe_right", "lung_middle_lobe_right",
          "lung_lower_lobe_right"};
}

std::vector<int> resolve_labels(const LabelMap& map, const std::string& name,
                                const std::vector<std::string>& selection) {
  std::set<int> present(map.labels.begin(), map.labels.end());
  std::vector<int> out;
  auto add = [&](int value) {
    if (std::find(out.begin(), out.end(), value) == out.end()) out.push_back(value);
  };
  for (const std::string& entry : selection) {
    if (const std::optional<int> number = parse_int(entry)) {
      if (!present.count(*number)) {
        throw ValueError("label " + std::to_string(*number) + " is not in " + name +
                         " (labels present: " + list_present(present) + ")");
      }
      add(*number);
      continue;
    }
    const auto found =
        std::find_if(map.segments.begin(), map.segments.end(), [&](const Segment& s) { return s.name == entry; });
    if (found == map.segments.end()) {
      if (map.segments.empty()) {
        throw ValueError(fmt::format("\"{}\" is not a segment of {}: it names no segments (a .seg.nrrd, a "
                                     "TotalSegmentator file or mask folder does); give label numbers (labels present: "
                                     "{})",
                                     entry, name, list_present(present)));
      }
      throw ValueError(
          fmt::format("\"{}\" is not a segment of {} (segments: {})", entry, name, list_segments(map.segments)));
    }
    if (!present.count(found->label)) {
      throw ValueError(fmt::format("segment \"{}\" (label {}) has no voxels in {} (labels present: {})", entry,
                                   found->label, name, list_present(present)));
    }
    add(found->label);
  }
  return out;
}

namespace detail {

std::vector<Segment> segments_of_present_labels(const std::vector<Segment>& classes,
                                                const std::vector<std::int32_t>& labels) {
  const std::set<int> present(labels.begin(), labels.end());
  std::vector<Segment> out;
  for (const Segment& s : classes) {
    if (present.count(s.label)) out.push_back(s);
  }
  return out;
}

// <Label Key="10" ...><![CDATA[lung_upper_lobe_left]]></Label>, as TotalSegmentator writes
// (nifti_ext_header.py, a CaretExtension of code 0); anything else gives no segments.
std::vector<Segment> caret_label_table(const std::string& xml) {
  std::vector<Segment> out;
  if (xml.find("<LabelTable") == std::string::npos) return out;
  std::size_t at = 0;
  while ((at = xml.find("<Label ", at)) != std::string::npos) {
    const std::size_t close = xml.find('>', at);
    const std::size_t end = xml.find("</Label>", at);
    if (close == std::string::npos || end == std::string::npos || end < close) break;
    const std::string tag = xml.substr(at, close - at);
    at = end + 8;
    const std::size_t key = tag.find("Key=\"");
    if (key == std::string::npos) continue;
    const std::size_t key_end = tag.find('"', key + 5);
    const std::optional<int> value = parse_int(std::string_view(tag).substr(key + 5, key_end - key - 5));
    std::string text = xml.substr(close + 1, end - close - 1);
    if (text.starts_with("<![CDATA[") && text.ends_with("]]>")) text = text.substr(9, text.size() - 12);
    if (value && !text.empty()) out.push_back({text, *value});
  }
  return out;
}

}  // namespace detail
}  // namespace pneuma::image
