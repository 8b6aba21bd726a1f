// The GenICam description served by MockGvCamera: Aravis's fake camera register map with the
// SFNC features our driver and clients use added (ExposureTime, Gain, AcquisitionFrameRate in
// AcquisitionControl) and the pixel formats limited to Mono8, Mono16, BayerRG8 and RGB8.
// SensorWidth/SensorHeight read registers that the server sets (10 MP by default).
#include "mocks/camera/mock_gv_camera.h"

namespace msmcal::sim {

std::string GenicamXml() {
  static const char* const kXml = R"XML(<?xml version="1.0" encoding="utf-8"?>

<RegisterDescription
	ModelName="MSMCAL-SIM"
	VendorName="msmcal"
	StandardNameSpace="None"
	SchemaMajorVersion="1"
	SchemaMinorVersion="0"
	SchemaSubMinorVersion="1"
	MajorVersion="1"
	MinorVersion="0"
	SubMinorVersion="0"
	ToolTip="msmcal simulated rig camera (Aravis GV fake camera core)"
	ProductGuid="0"
	VersionGuid="0"
	xmlns="http://www.genicam.org/GenApi/Version_1_0"
	xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"
	xsi:schemaLocation="http://www.genicam.org/GenApi/Version_1_0 GenApiSchema.xsd">

	<Category Name="Root" NameSpace="Standard">
		<pFeature>DeviceControl</pFeature>
		<pFeature>ImageFormatControl</pFeature>
		<pFeature>AcquisitionControl</pFeature>
		<pFeature>AnalogControl</pFeature>
		<pFeature>TransportLayerControl</pFeature>
		<pFeature>Debug</pFeature>
	</Category>

	<!-- Device control -->

	<Category Name="DeviceControl" NameSpace="Standard">
		<pFeature>DeviceVendorName</pFeature>
		<pFeature>DeviceModelName</pFeature>
		<pFeature>DeviceManufacturerInfo</pFeature>
		<pFeature>DeviceID</pFeature>
		<pFeature>DeviceVersion</pFeature>
	</Category>

	<StringReg Name="DeviceVendorName" NameSpace="Standard">
		<DisplayName>Vendor Name</DisplayName>
		<Address>0x48</Address>
		<Length>32</Length>
		<AccessMode>RO</AccessMode>
		<pPort>Device</pPort>
	</StringReg>

	<StringReg Name="DeviceModelName" NameSpace="Standard">
		<DisplayName>Model Name</DisplayName>
		<Address>0x68</Address>
		<Length>32</Length>
		<AccessMode>RO</AccessMode>
		<pPort>Device</pPort>
	</StringReg>

	<StringReg Name="DeviceManufacturerInfo" NameSpace="Standard">
		<DisplayName>Manufacturer Info</DisplayName>
		<Address>0xa8</Address>
		<Length>48</Length>
		<AccessMode>RO</AccessMode>
		<pPort>Device</pPort>
	</StringReg>

	<StringReg Name="DeviceID" NameSpace="Standard">
		<DisplayName>Device ID</DisplayName>
		<Address>0xd8</Address>
		<Length>16</Length>
		<AccessMode>RO</AccessMode>
		<pPort>Device</pPort>
	</StringReg>

	<StringReg Name="DeviceVersion" NameSpace="Standard">
		<DisplayName>Device Version</DisplayName>
		<Address>0x88</Address>
		<Length>32</Length>
		<AccessMode>RO</AccessMode>
		<pPort>Device</pPort>
	</StringReg>

	<!-- Image format control -->

	<Category Name="ImageFormatControl" NameSpace="Standard">
		<pFeature>SensorHeight</pFeature>
		<pFeature>SensorWidth</pFeature>
		<pFeature>OffsetX</pFeature>
		<pFeature>OffsetY</pFeature>
		<pFeature>Width</pFeature>
		<pFeature>Height</pFeature>
		<pFeature>BinningHorizontal</pFeature>
		<pFeature>BinningVertical</pFeature>
		<pFeature>PixelFormat</pFeature>
	</Category>

	<Integer Name="SensorHeight" NameSpace="Standard">
		<Description>Full height of image sensor.</Description>
		<pValue>SensorHeightRegister</pValue>
	</Integer>

	<IntReg Name="SensorHeightRegister" NameSpace="Custom">
		<Address>0x118</Address>
		<Length>4</Length>
		<AccessMode>RO</AccessMode>
		<pPort>Device</pPort>
		<Sign>Unsigned</Sign>
		<Endianess>BigEndian</Endianess>
	</IntReg>

	<Integer Name="SensorWidth" NameSpace="Standard">
		<Description>Full height of image sensor.</Description>
		<pValue>SensorWidthRegister</pValue>
	</Integer>

	<IntReg Name="SensorWidthRegister" NameSpace="Custom">
		<Address>0x11c</Address>
		<Length>4</Length>
		<AccessMode>RO</AccessMode>
		<pPort>Device</pPort>
		<Sign>Unsigned</Sign>
		<Endianess>BigEndian</Endianess>
	</IntReg>

	<Integer Name="OffsetX" NameSpace="Standard">
		<Description>X offset of image, in pixels.</Description>
		<pValue>OffsetXRegister</pValue>
		<Min>0</Min>
		<pMax>SensorWidth</pMax>
		<Inc>1</Inc>
	</Integer>

	<IntReg Name="OffsetXRegister" NameSpace="Custom">
		<Address>0x130</Address>
		<Length>4</Length>
		<AccessMode>RW</AccessMode>
		<pPort>Device</pPort>
		<Sign>Unsigned</Sign>
		<Endianess>BigEndian</Endianess>
	</IntReg>

	<Integer Name="OffsetY" NameSpace="Standard">
		<Description>Y offset of image, in pixels.</Description>
		<pValue>OffsetYRegister</pValue>
		<Min>0</Min>
		<pMax>SensorHeight</pMax>
		<Inc>1</Inc>
	</Integer>

	<IntReg Name="OffsetYRegister" NameSpace="Custom">
		<Address>0x134</Address>
		<Length>4</Length>
		<AccessMode>RW</AccessMode>
		<pPort>Device</pPort>
		<Sign>Unsigned</Sign>
		<Endianess>BigEndian</Endianess>
	</IntReg>

	<Integer Name="Width" NameSpace="Standard">
		<Description>Width of image, in pixels.</Description>
		<pValue>WidthRegister</pValue>
		<Min>1</Min>
		<pMax>SensorWidth</pMax>
		<Inc>1</Inc>
	</Integer>

	<IntReg Name="WidthRegister" NameSpace="Custom">
		<Address>0x100</Address>
		<Length>4</Length>
		<AccessMode>RW</AccessMode>
		<pPort>Device</pPort>
		<Sign>Unsigned</Sign>
		<Endianess>BigEndian</Endianess>
	</IntReg>

	<Integer Name="Height" NameSpace="Standard">
		<Description>Height of image, in pixels.</Description>
		<pValue>HeightRegister</pValue>
		<Min>1</Min>
		<pMax>SensorHeight</pMax>
		<Inc>1</Inc>
	</Integer>

	<IntReg Name="HeightRegister" NameSpace="Custom">
		<Address>0x104</Address>
		<Length>4</Length>
		<AccessMode>RW</AccessMode>
		<pPort>Device</pPort>
		<Sign>Unsigned</Sign>
		<Endianess>BigEndian</Endianess>
	</IntReg>

	<Integer Name="BinningHorizontal" NameSpace="Standard">
		<Description>Binning in horizontal direction.</Description>
		<pValue>BinningHorizontalRegister</pValue>
		<Min>1</Min>
		<Max>16</Max>
	</Integer>

	<IntReg Name="BinningHorizontalRegister" NameSpace="Custom">
		<Address>0x108</Address>
		<Length>4</Length>
		<AccessMode>RW</AccessMode>
		<pPort>Device</pPort>
		<Sign>Unsigned</Sign>
		<Endianess>BigEndian</Endianess>
	</IntReg>

	<Integer Name="BinningVertical" NameSpace="Standard">
		<Description>Binning in vertical direction.</Description>
		<pValue>BinningVerticalRegister</pValue>
		<Min>1</Min>
		<Max>16</Max>
	</Integer>

	<IntReg Name="BinningVerticalRegister" NameSpace="Custom">
		<Address>0x10c</Address>
		<Length>4</Length>
		<AccessMode>RW</AccessMode>
		<pPort>Device</pPort>
		<Sign>Unsigned</Sign>
		<Endianess>BigEndian</Endianess>
	</IntReg>

	<Enumeration Name="PixelFormat" NameSpace="Standard">
		<DisplayName>Pixel format</DisplayName>
		<EnumEntry Name="BayerRG8" NameSpace="Standard">
			<Value>17301513</Value>
		</EnumEntry>
		<EnumEntry Name="Mono8" NameSpace="Standard">
			<Value>17301505</Value>
		</EnumEntry>
		<EnumEntry Name="RGB8" NameSpace="Standard">
			<Value>35127316</Value>
		</EnumEntry>
		<EnumEntry Name="Mono16" NameSpace="Standard">
			<Value>17825799</Value>
		</EnumEntry>
		<pValue>PixelFormatRegister</pValue>
	</Enumeration>

	<IntReg Name="PixelFormatRegister" NameSpace="Custom">
		<Address>0x128</Address>
		<Length>4</Length>
		<AccessMode>RW</AccessMode>
		<pPort>Device</pPort>
		<Sign>Unsigned</Sign>
		<Endianess>BigEndian</Endianess>
	</IntReg>

	<!-- Acquisition control -->

	<Category Name="AcquisitionControl" NameSpace="Custom">
		<pFeature>AcquisitionMode</pFeature>
		<pFeature>AcquisitionStart</pFeature>
		<pFeature>AcquisitionStop</pFeature>
		<pFeature>TriggerSelector</pFeature>
		<pFeature>TriggerMode</pFeature>
		<pFeature>TriggerSoftware</pFeature>
		<pFeature>TriggerSource</pFeature>
		<pFeature>TriggerActivation</pFeature>
		<pFeature>AcquisitionFrameRate</pFeature>
		<pFeature>ExposureTime</pFeature>
		<pFeature>ExposureTimeAbs</pFeature>
	</Category>

	<Command Name="AcquisitionStart" NameSpace="Standard">
		<Description>Start acquisition.</Description>
		<pValue>AcquisitionCommandRegister</pValue>
		<CommandValue>1</CommandValue>
	</Command>

	<Command Name="AcquisitionStop" NameSpace="Standard">
		<Description>Stop acquisition.</Description>
		<pValue>AcquisitionCommandRegister</pValue>
		<CommandValue>0</CommandValue>
	</Command>

	<IntReg Name="AcquisitionCommandRegister" NameSpace="Custom">
		<Address>0x124</Address>
		<Length>4</Length>
		<AccessMode>WO</AccessMode>
		<pPort>Device</pPort>
		<Sign>Unsigned</Sign>
		<Endianess>BigEndian</Endianess>
	</IntReg>

	<Enumeration Name="AcquisitionMode" NameSpace="Standard">
		<DisplayName>Acquisition mode</DisplayName>
		<EnumEntry Name="Continuous" NameSpace="Standard">
			<Value>1</Value>
		</EnumEntry>
		<EnumEntry Name="SingleFrame" NameSpace="Standard">
			<Value>2</Value>
		</EnumEntry>
		<EnumEntry Name="MultiFrame" NameSpace="Standard">
			<Value>3</Value>
		</EnumEntry>
		<pValue>AcquisitionModeRegister</pValue>
	</Enumeration>

	<IntReg Name="AcquisitionModeRegister" NameSpace="Custom">
		<Address>0x12c</Address>
		<Length>4</Length>
		<AccessMode>RW</AccessMode>
		<pPort>Device</pPort>
		<Sign>Unsigned</Sign>
		<Endianess>BigEndian</Endianess>
	</IntReg>

	<Float Name="AcquisitionFrameRate" NameSpace="Standard">
	  <pValue>AcquisitionFrameRateConverter</pValue>
	</Float>

	<Converter Name="AcquisitionFrameRateConverter">
		<Description>Frame rate, in frames per second.</Description>
		<FormulaTo>(1000000 / FROM)</FormulaTo>
		<FormulaFrom>(1000000 / TO)</FormulaFrom>
		<pValue>AcquisitionFramePeriod</pValue>
	</Converter>

	<Integer Name="AcquisitionFramePeriod" NameSpace="Custom">
	  <pValue>AcquisitionFramePeriodRegister</pValue>
	  <Min>1000</Min>
	  <Max>10000000</Max>
	</Integer>

	<IntReg Name="AcquisitionFramePeriodRegister" NameSpace="Custom">
		<Address>0x138</Address>
		<Length>4</Length>
		<AccessMode>RW</AccessMode>
		<pPort>Device</pPort>
		<Sign>Unsigned</Sign>
		<Endianess>BigEndian</Endianess>
	</IntReg>

	<Enumeration Name="TriggerSelector" NameSpace="Standard">
		<EnumEntry Name="FrameStart" NameSpace="Standard">
			<Value>0</Value>
		</EnumEntry>
		<EnumEntry Name="AcquisitionStart" NameSpace="Standard">
			<Value>1</Value>
		</EnumEntry>
		<pValue>TriggerSelectorInteger</pValue>
	</Enumeration>

	<Integer Name="TriggerSelectorInteger" NameSpace="Custom">
		<Value>0</Value>
	</Integer>

	<Enumeration Name="TriggerMode" NameSpace="Standard">
		<DisplayName>Trigger mode</DisplayName>
		<EnumEntry Name="Off" NameSpace="Standard">
			<Value>0</Value>
		</EnumEntry>
		<EnumEntry Name="On" NameSpace="Standard">
			<Value>1</Value>
		</EnumEntry>
		<pValue>TriggerModeRegister</pValue>
	</Enumeration>

	<IntReg Name="TriggerModeRegister" NameSpace="Custom">
		<Address>0x300</Address>
		<pIndex Offset="0x20">TriggerSelectorInteger</pIndex>
		<Length>4</Length>
		<AccessMode>RW</AccessMode>
		<pPort>Device</pPort>
		<Sign>Unsigned</Sign>
		<Endianess>BigEndian</Endianess>
	</IntReg>

	<Enumeration Name="TriggerSource" NameSpace="Standard">
		<DisplayName>Trigger source</DisplayName>
		<EnumEntry Name="Line0" NameSpace="Standard">
			<Value>0</Value>
		</EnumEntry>
		<EnumEntry Name="Software" NameSpace="Standard">
			<Value>1</Value>
		</EnumEntry>
		<pValue>TriggerSourceRegister</pValue>
	</Enumeration>

	<IntReg Name="TriggerSourceRegister" NameSpace="Custom">
		<Address>0x304</Address>
		<pIndex Offset="0x20">TriggerSelectorInteger</pIndex>
		<Length>4</Length>
		<AccessMode>RW</AccessMode>
		<pPort>Device</pPort>
		<Sign>Unsigned</Sign>
		<Endianess>BigEndian</Endianess>
	</IntReg>

	<Enumeration Name="TriggerActivation" NameSpace="Standard">
		<DisplayName>Trigger activation</DisplayName>
		<EnumEntry Name="RisingEdge" NameSpace="Standard">
			<Value>0</Value>
		</EnumEntry>
		<pValue>TriggerActivationRegister</pValue>
	</Enumeration>

	<IntReg Name="TriggerActivationRegister" NameSpace="Custom">
		<Address>0x308</Address>
		<pIndex Offset="0x20">TriggerSelectorInteger</pIndex>
		<Length>4</Length>
		<AccessMode>RW</AccessMode>
		<pPort>Device</pPort>
		<Sign>Unsigned</Sign>
		<Endianess>BigEndian</Endianess>
	</IntReg>

	<Command Name="TriggerSoftware" NameSpace="Standard">
		<Description>Generates an internal trigger. TriggerSource must be set to Software.</Description>
		<pValue>TriggerSoftwareCommandRegister</pValue>
		<CommandValue>1</CommandValue>
	</Command>

	<IntReg Name="TriggerSoftwareCommandRegister" NameSpace="Custom">
		<Address>0x30c</Address>
		<Length>4</Length>
		<AccessMode>WO</AccessMode>
		<pPort>Device</pPort>
		<Sign>Unsigned</Sign>
		<Endianess>BigEndian</Endianess>
	</IntReg>

	<Float Name="ExposureTimeAbs" NameSpace="Standard">
		<Description>Exposure duration, in microseconds.</Description>
		<pValue>ExposureTimeAbsConverter</pValue>
		<Min>10.0</Min>
		<Max>10000000.0</Max>
	</Float>

	<Converter Name="ExposureTimeAbsConverter" NameSpace="Custom">
		<FormulaTo>FROM</FormulaTo>
		<FormulaFrom>TO</FormulaFrom>
		<pValue>ExposureTimeAbsRegister</pValue>
	</Converter>

	<IntReg Name="ExposureTimeAbsRegister" NameSpace="Custom">
		<Address>0x120</Address>
		<Length>4</Length>
		<AccessMode>RW</AccessMode>
		<pPort>Device</pPort>
		<Sign>Unsigned</Sign>
		<Endianess>BigEndian</Endianess>
	</IntReg>

	<!-- SFNC ExposureTime on the same register as ExposureTimeAbs -->

	<Float Name="ExposureTime" NameSpace="Standard">
		<Description>Exposure duration, in microseconds.</Description>
		<pValue>ExposureTimeAbsConverter</pValue>
		<Min>10.0</Min>
		<Max>10000000.0</Max>
		<Unit>us</Unit>
	</Float>

	<!-- Analog control -->

	<Category Name="AnalogControl" NameSpace="Custom">
		<pFeature>Gain</pFeature>
		<pFeature>GainRaw</pFeature>
		<pFeature>GainAuto</pFeature>
	</Category>

	<Float Name="Gain" NameSpace="Standard">
		<Description>Gain, in dB (whole steps of the raw gain register).</Description>
		<pValue>GainConverter</pValue>
		<Min>0.0</Min>
		<Max>10.0</Max>
		<Unit>dB</Unit>
	</Float>

	<Converter Name="GainConverter" NameSpace="Custom">
		<FormulaTo>FROM</FormulaTo>
		<FormulaFrom>TO</FormulaFrom>
		<pValue>GainRawRegister</pValue>
	</Converter>

	<Integer Name="GainRaw" NameSpace="Standard">
		<Description>Raw gain.</Description>
		<pValue>GainRawRegister</pValue>
		<Min>0</Min>
		<Max>10</Max>
	</Integer>

	<IntReg Name="GainRawRegister" NameSpace="Custom">
		<Address>0x110</Address>
		<Length>4</Length>
		<AccessMode>RW</AccessMode>
		<pPort>Device</pPort>
		<Sign>Unsigned</Sign>
		<Endianess>BigEndian</Endianess>
	</IntReg>

	<Enumeration Name="GainAuto" NameSpace="Standard">
		<Description>Automatic gain mode.</Description>
		<EnumEntry Name="Off" NameSpace="Standard">
			<Value>1</Value>
		</EnumEntry>
		<EnumEntry Name="Once" NameSpace="Standard">
			<Value>3</Value>
		</EnumEntry>
		<EnumEntry Name="Continuous" NameSpace="Standard">
			<Value>2</Value>
		</EnumEntry>
		<pValue>GainAutoRegister</pValue>
	</Enumeration>

	<IntReg Name="GainAutoRegister" NameSpace="Custom">
		<Address>0x114</Address>
		<Length>4</Length>
		<AccessMode>RW</AccessMode>
		<pPort>Device</pPort>
		<Sign>Unsigned</Sign>
		<Endianess>BigEndian</Endianess>
	</IntReg>

	<!-- Transport layer control -->

	<Category Name="TransportLayerControl" NameSpace="Standard">
		<pFeature>PayloadSize</pFeature>
	</Category>

	<IntSwissKnife Name="PayloadSize" NameSpace="Standard">
		<pVariable Name="WIDTH">Width</pVariable>
		<pVariable Name="HEIGHT">Height</pVariable>
		<pVariable Name="PIXELFORMAT">PixelFormat</pVariable>
		<Formula>WIDTH * HEIGHT * ((PIXELFORMAT>>16)&amp;0xFF) / 8</Formula>
	</IntSwissKnife>

	<Integer Name="TLParamsLocked">
		<ToolTip> Indicates whether a live grab is under way</ToolTip>
		<Visibility>Invisible</Visibility>
		<Value>0</Value>
		<Min>0</Min>
		<Max>1</Max>
	</Integer>

	<!-- Debug -->

	<Category Name="Debug" NameSpace="Standard">
		<pFeature>TestRegister</pFeature>
	</Category>

	<Boolean Name="TestBoolean" NameSpace="Custom">
		<pValue>TestRegister</pValue>
		<OnValue>321</OnValue>
		<OffValue>123</OffValue>
	</Boolean>

	<IntReg Name="TestRegister" NameSpace="Custom">
		<Address>0x1f0</Address>
		<Length>4</Length>
		<AccessMode>RW</AccessMode>
		<pPort>Device</pPort>
		<Sign>Unsigned</Sign>
		<Endianess>BigEndian</Endianess>
	</IntReg>

	<StructReg Comment="TestStructReg">
		<Address>0x1f0</Address>
		<Length>4</Length>
		<AccessMode>RW</AccessMode>
		<pPort>Device</pPort>
		<Endianess>BigEndian</Endianess>

		<StructEntry Name="StructEntry_16_31" NameSpace="Custom">
			<LSB>31</LSB>
			<MSB>16</MSB>
			<Sign>Signed</Sign>
		</StructEntry>

		<StructEntry Name="StructEntry_0_15" NameSpace="Custom">
			<LSB>15</LSB>
			<MSB>0</MSB>
			<Sign>Unsigned</Sign>
		</StructEntry>

		<StructEntry Name="StructEntry_15" NameSpace="Custom">
			<Bit>15</Bit>
		</StructEntry>

		<StructEntry Name="StructEntry_0_31" NameSpace="Custom">
			<LSB>31</LSB>
			<MSB>0</MSB>
			<Sign>Unsigned</Sign>
		</StructEntry>
	</StructReg>

	<StringReg Name="TestStringReg" NameSpace="Custom">
		<Address>0x200</Address>
		<Length>32</Length>
		<AccessMode>RW</AccessMode>
		<pPort>Device</pPort>
	</StringReg>

	<!-- Port -->

	<Port Name="Device" NameSpace="Standard">
	</Port>

</RegisterDescription>

)XML";
  return kXml;
}

}  // namespace msmcal::sim
