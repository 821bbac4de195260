#pragma once
// DICOM: a CT series (a folder of CT Image Storage files, one slice each) read as a scalar image,
// and the identity of the patient, study and frame of reference it belongs to, which the DICOM
// outputs carry over (docs/formats.md, "DICOM"). DCMTK's dcmdata in src/dicom_read.cpp only.
#include <string>

namespace pneuma::image {

// What a run keeps of the series it read: the patient and study (the outputs join the same
// study) and the frame of reference (the outputs share the input's coordinates). Empty strings
// for attributes the files do not hold.
struct DicomSource {
  std::string patient_name, patient_id, patient_birth_date, patient_sex;
  std::string study_instance_uid, study_date, study_time, study_id, accession_number, referring_physician_name,
      study_description;
  std::string frame_of_reference_uid, position_reference_indicator;
  std::string series_instance_uid, series_description, patient_position;
  std::string specific_character_set;  // (0008,0005): how the names' bytes are to be read
};

}  // namespace pneuma::image
